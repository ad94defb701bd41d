"""Fits into holes (cellrunner/planning/insert_fit.py, issue 33): ``contact:`` lets the peg
touch the walls, not press into them; an interference fit is a press fit only where the
insert declares one (``force: {min, max}``, under the arm's force limit), and a press fit
whose force never builds up to ``min`` fails at run time (3)."""

from __future__ import annotations

import contextlib
import io

from cellrunner.cli.main import main
from tests.planning.tight_peg import WALLS, peg_cell, peg_task
from tests.rig import json_of, main_json

CONTACT = f", contact: [{', '.join(WALLS)}]"


def _write(tmp_path, gap_m: float, force: str = "{max: 10}") -> tuple[str, str]:
    cell, task = tmp_path / "cell.yaml", tmp_path / "task.yaml"
    cell.write_text(peg_cell(gap_m))
    task.write_text(peg_task(CONTACT, CONTACT).replace("force: {max: 10}", f"force: {force}"))
    return str(cell), str(task)


def test_an_interference_fit_without_force_min_is_a_jam(tmp_path):
    out = json_of("check", *_write(tmp_path, -0.0001), "--no-cache")
    assert not out["ok"]
    (error,) = out["errors"]
    assert error.startswith("step 8 insert 'hole': part 'peg' overlaps fixture 'wall_"), error
    assert "(an interference fit): it jams" in error


def test_a_declared_press_fit_is_approved_under_the_arms_force_limit(tmp_path):
    out = json_of("check", *_write(tmp_path, -0.0001, "{min: 5, max: 40}"), "--no-cache")
    assert out["ok"], out["errors"]
    out = json_of("check", *_write(tmp_path, -0.0001, "{min: 5, max: 200}"), "--no-cache")
    (error,) = out["errors"]
    assert "the press fit asks for up to 200 N (force.max) but the arm stops above 150 N" in error


def test_a_press_fit_deeper_than_a_press_fit_is_a_jam(tmp_path):
    out = json_of("check", *_write(tmp_path, -0.0005, "{min: 5, max: 40}"), "--no-cache")
    (error,) = out["errors"]
    assert "part 'peg' is 0.50 mm into fixture 'wall_" in error
    assert "more than a press fit's 0.2 mm: it jams" in error


def test_force_min_over_max_is_a_located_error(tmp_path):
    cell, task = _write(tmp_path, 0.0005, "{min: 20, max: 10}")
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["validate", cell, task]) == 2
    text = err.getvalue()
    assert "task.yaml:7:" in text and "force min 20 N is not below max 10 N" in text, text


def test_a_press_fit_whose_force_never_builds_up_is_refused_and_fails_in_the_twin(
    tmp_path, monkeypatch
):
    """The peg slides into a hole 0.5 mm wider on each side: nothing presses, so the
    press fit is never made (a worn hole, the wrong part): check refuses it, and the
    twin, with check's fit rule off, fails the insert (3)."""
    cell, task = _write(tmp_path, 0.0005, "{min: 8, max: 10}")
    out = json_of("check", cell, task, "--no-cache")
    (error,) = out["errors"]
    assert "the press fit is never made: the held part does not overlap" in error
    from cellrunner.steps import insert

    monkeypatch.setattr(insert.Insert, "check_line", lambda *args: None)
    code, out = main_json("dry-run", cell, task)
    assert code == 1
    assert out["result_code"] == 3, out
    assert out["result_text"].startswith("press fit not made: the force built up to "), out
    assert "under the 8 N of force.min" in out["result_text"]
