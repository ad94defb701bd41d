"""Declared press fits (``insert: {force: {min, max}}``, issue 33) in check and the twin,
on generated cells as bench/cellgen_holes.py wrote them (tests/data/generated):

- s7012 (a UR10 presses a square pin 0.1 mm wider than its hole on each face, window
  24.2-48.9 N): check approves, and the twin, where every declared press fit stopped at
  thousands of newtons on its rigid walls, presses it in, its force building up inside
  the window, and leaves it where it was pressed;
- s11 press_fit_loose (the same window on a hole with clearance): check refuses it, the
  fit is never made; the twin fails it (3) for the force that never built up;
- s11 press_fit_jam (0.4-0.6 mm per face): check refuses it as a jam; with check's fit
  rule off, the twin jams it too;
- s100652 (a UR10, 0.1 mm per face): the pads' soft contacts let the pin creep 0.24 mm
  along them as the lift dragged it off its table, and the jaws' weld held it there: it
  met a wall 0.31 mm deep (100). The weld now holds the part where the jaws closed on it.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from bench.agreement import cli
from tests.agreement.generated import approved_and_rehearsed, copied


def test_a_declared_press_fit_is_approved_and_pressed_in_within_its_window(tmp_path):
    cell, task = copied("s7012-ur10-press_fit", tmp_path)
    _, run = approved_and_rehearsed(cell, task)
    # the pin stays where the insert pressed it: under the hole's mouth, not on its floor
    from ruamel.yaml import YAML

    c = YAML(typ="safe").load(Path(cell).read_text())
    hole = c["frames"]["hole"]["xyz"]
    half = c["parts"][0]["box"]["size"][2] / 2
    pin = run["parts_end_m"]["pin"]
    assert math.dist(pin[:2], hole[:2]) < 0.001
    t = YAML(typ="safe").load(Path(task).read_text())
    insert = next(s["insert"] for s in t["steps"] if isinstance(s, dict) and "insert" in s)
    lo, hi = insert["expect_depth"]
    depth_m = hole[2] - half - (pin[2] - half)  # how far the pin's tip went past the mouth
    assert lo - 0.001 <= depth_m <= hi + 0.001


def test_the_twin_presses_a_declared_fit_with_the_force_of_its_window(tmp_path):
    """The wrist force the insert reads builds up past force.min and stays under force.max:
    the step says what it measured."""
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.sim.press_fits import fit_force_N, press_fit_forces

    cell, task = copied("s7012-ur10-press_fit", tmp_path)
    loaded = load_task(task, load_cell(cell))
    (insert,) = [s for s in loaded.steps if s.kind == "insert"]
    low, high = insert.args.force.min, insert.args.force.max
    forces = dict(press_fit_forces([loaded]))
    assert set(forces) == {"wall_xm", "wall_xp", "wall_ym", "wall_yp"}
    assert forces["wall_xm"] == pytest.approx(fit_force_N(low, high))
    _, run = cli("dry-run", cell, task)
    (row,) = [s for s in run["steps"] if s["kind"] == "insert"]
    match = re.fullmatch(r"press fit made: ([0-9.]+) N by ([0-9.]+) mm", row["message"])
    assert match, row
    assert low <= float(match[1]) < high


def test_a_declared_press_fit_on_a_hole_with_clearance_is_refused(tmp_path):
    cell, task = copied("s11-ur5e-press_fit_loose", tmp_path)
    code, checked = cli("check", cell, task, "--no-cache")
    assert code == 1
    (error,) = checked["errors"]
    assert "the press fit is never made: the held part does not overlap wall_xm" in error
    assert "cannot build up to the" in error and "N of force.min (it would fail, 3)" in error


def test_a_declared_press_fit_far_too_tight_is_refused_as_a_jam(tmp_path):
    cell, task = copied("s11-ur5-press_fit_jam", tmp_path)
    code, checked = cli("check", cell, task, "--no-cache")
    assert code == 1
    (error,) = checked["errors"]
    assert "more than a press fit's 0.2 mm: it jams" in error


def test_the_twin_fails_a_loose_press_fit_for_its_force(tmp_path, twin_only):
    cell, task = copied("s11-ur5e-press_fit_loose", tmp_path)
    _, run = cli("dry-run", cell, task)
    assert run["result_code"] == 3, run
    assert "press fit not made: the force built up to" in run["result_text"]


def test_the_twin_jams_a_press_fit_far_too_tight(tmp_path, twin_only):
    cell, task = copied("s11-ur5-press_fit_jam", tmp_path)
    _, run = cli("dry-run", cell, task)
    assert run["result_code"] in (3, 100), run  # stopped at the mouth, or a protective stop
    assert run["result_code"] != 0


def test_a_pin_the_lift_drags_along_the_pads_is_held_where_it_was_gripped(tmp_path):
    approved_and_rehearsed(*copied("s100652-ur10-press_fit", tmp_path))
