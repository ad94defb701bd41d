"""The reference cells in cells/ in `dry-run`: the normal job and each fault that applies,
with the SPEC's result codes; the force steps' failures (blocked insert, no contact)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.cells.reference import PALLETIZER, PEG, probe_task
from tests.conftest import ROOT
from tests.rig import dry_run, main_json


def failed(out: dict) -> list[tuple[int, str]]:
    return [(s["index"], s["message"]) for s in out["steps"] if s["status"] == "failed"]


def test_palletizer_places_the_carton_on_its_slot():
    out = dry_run(*PALLETIZER, "-p", "slot=3")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    x, y, z = out["parts_end_m"]["carton"]
    # slot 3: row 1, col 1 -> 0.22 m along the frame's X, 0.17 m along its Y (world -Y)
    assert (x, y) == pytest.approx((0.69 + 0.22, 0.285 - 0.17), abs=0.005)
    assert z == pytest.approx(0.14 + 0.05, abs=0.003)  # resting on the pallet


def test_palletizer_grip_miss_is_no_part():
    out = dry_run(*PALLETIZER, "--inject", "grip_miss@grip")
    assert out["result_code"] == 1
    assert out["retries"] == 1
    assert (
        failed(out)
        == [
            (
                5,
                "attempt 1 failed: vacuum_ok not true within 1 s (no vacuum: the cups sealed on "
                "nothing); vacuum_ok not true within 1 s (no vacuum: the cups sealed on nothing)",
            )
        ]
        or failed(out)[0][0] == 5
    )


def test_palletizer_part_slip_is_part_lost():
    out = dry_run(*PALLETIZER, "--inject", "part_slip@approach#2")
    assert out["result_code"] == 2
    assert failed(out) == [(7, "part lost in transit: the vacuum switch dropped")]


def test_palletizer_plc_disconnect_holds_and_resumes_with_suction():
    out = dry_run(*PALLETIZER, "--inject", "plc_disconnect@approach#2")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["cycle_time_s"] > out["planned_cycle_time_s"] + 1.5  # held while the PLC was away


def test_palletizer_estop_is_101():
    out = dry_run(*PALLETIZER, "--inject", "estop@approach#2")
    assert out["result_code"] == 101


def test_peg_insert_reaches_its_depth():
    out = dry_run(*PEG)
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    x, y, z = out["parts_end_m"]["peg"]
    assert (x, y) == pytest.approx((0.30, 0.15), abs=0.002)
    assert z == pytest.approx(0.81 + 0.05, abs=0.003)  # in the hole, on its floor


def test_peg_grip_miss_and_slip():
    assert dry_run(*PEG, "--inject", "grip_miss@grip")["result_code"] == 1
    out = dry_run(*PEG, "--inject", "part_slip@approach#2")
    assert out["result_code"] == 2


def test_peg_protective_stop_during_insert_resumes():
    out = dry_run(*PEG, "--inject", "protective_stop@insert")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["cycle_time_s"] > out["planned_cycle_time_s"] + 5.0  # the controller's unlock delay


@pytest.fixture(scope="module")
def shallow(tmp_path_factory):
    """The peg cell with the hole's floor 10 mm under its mouth: the insert is blocked early."""
    root = tmp_path_factory.mktemp("shallow")
    (root / "cells").mkdir()
    (root / "tasks").mkdir()
    cell = (
        (ROOT / PEG[0])
        .read_text()
        .replace(
            "{name: hole_floor, box: {size: [0.022, 0.022, 0.01]}, pose: {xyz: [0.30, 0.15, 0.805]}}",
            "{name: hole_floor, box: {size: [0.022, 0.022, 0.03]}, pose: {xyz: [0.30, 0.15, 0.815]}}",
        )
    )
    (root / "cells" / "peg.yaml").write_text(cell)
    (root / "tasks" / "peg_insert.yaml").write_text((ROOT / PEG[1]).read_text())
    (root / "tasks" / "probe_far.yaml").write_text(probe_task(0.02))
    (root / "tasks" / "probe.yaml").write_text(probe_task(0.1))
    (root / "tasks" / "probe_world.yaml").write_text(
        probe_task(0.1).replace("direction: [0, 0, 1]", "direction: [0, 0, -1], frame: world")
    )
    return root


@pytest.fixture
def twin_only(monkeypatch):
    """check's fit rules off, in this process: since issue 33 check refuses an insert that
    meets the floor before its expect_depth, and these tests are about the twin's verdict."""
    from cellrunner.steps import _families, insert

    monkeypatch.setattr(insert.Insert, "check_line", lambda *args: None)
    monkeypatch.setattr(_families.FrameLine, "check_line", lambda *args: None)


def _dry_run_here(*args: str) -> dict:
    code, out = main_json("dry-run", *args)
    assert code == (0 if out["result_code"] == 0 else 1), out
    return out


def test_insert_blocked_early_is_place_failed(shallow, twin_only):
    out = _dry_run_here(
        str(shallow / "cells" / "peg.yaml"), str(shallow / "tasks" / "peg_insert.yaml")
    )
    assert out["result_code"] == 3
    ((index, message),) = failed(out)
    assert index == 7
    assert message.startswith("inserted ") and "expected 22.0-26.0 mm (stopped at " in message
    depth_mm = float(message.split()[1])
    assert 8.0 < depth_mm < 12.0  # the floor is 10 mm down


def test_move_until_contact_stops_at_the_block(shallow):
    out = dry_run(str(shallow / "cells" / "peg.yaml"), str(shallow / "tasks" / "probe.yaml"))
    assert out["result_code"] == 0, (out["result_text"], out["steps"])


def test_move_until_contact_in_world_axes(shallow):
    out = dry_run(str(shallow / "cells" / "peg.yaml"), str(shallow / "tasks" / "probe_world.yaml"))
    assert out["result_code"] == 0, (out["result_text"], out["steps"])


def test_report_plots_the_wrist_force(shallow, tmp_path, twin_only):
    out = _dry_run_here(
        str(shallow / "cells" / "peg.yaml"),
        str(shallow / "tasks" / "peg_insert.yaml"),
        "--report",
        str(tmp_path / "report"),
    )
    assert out["result_code"] == 3
    plot = tmp_path / "report" / "wrist_force.png"
    assert plot.is_file() and plot.stat().st_size > 10_000


def test_move_until_contact_without_contact_is_refused_before_it_moves(shallow):
    """A guarded line that meets nothing the cell file has within max_distance fails on
    every backend (no contact within 20 mm): check refuses it, so the job never starts
    (it ran, and the twin gave 1, before issue 24)."""
    out = dry_run(str(shallow / "cells" / "peg.yaml"), str(shallow / "tasks" / "probe_far.yaml"))
    assert out["result_code"] == 103
    assert out["result_text"].startswith(
        "step 3 move_until_contact: the guarded line meets nothing within its max_distance 20 mm"
    )


def check_json(cell: str, task: str) -> tuple[int, dict]:
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "check", cell, task, "--json"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    return r.returncode, json.loads(r.stdout)


def test_check_verifies_the_insert_line_and_names_the_contact():
    code, out = check_json(*PEG)
    assert code == 0
    row = next(s for s in out["steps"] if s["kind"] == "insert")
    assert row["message"] == (
        "guarded: stops above 10 N; 55 mm line checked; contact allowed with: "
        "wall_xm, wall_xp, wall_ym, wall_yp"
    )


def test_check_refuses_an_insert_that_drives_the_gripper_into_the_block(tmp_path):
    """Only the carried part may make the insert's contact: 40 mm deep, the jaws would
    reach 10 mm into the block around the hole."""
    task = tmp_path / "deep.yaml"
    task.write_text(
        (ROOT / PEG[1])
        .read_text()
        .replace("depth: 0.025", "depth: 0.04")
        .replace("expect_depth: [0.022, 0.026]", "expect_depth: [0.035, 0.041]")
    )
    code, out = check_json(PEG[0], str(task))
    assert code == 1
    row = next(s for s in out["steps"] if s["kind"] == "insert")
    assert row["status"] == "failed"
    assert "tool 'jaw_" in row["message"] and "fixture 'wall_" in row["message"], row["message"]
