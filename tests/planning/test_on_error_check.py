"""``check`` verifies a task's on_error steps from every state a failure can leave the
arm in (SPEC section 11): each one's row says from how many states it was verified, an
infeasible one is named with the state it fails from, and a job whose on_error cannot
run is refused like any infeasible job."""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from cellrunner.cli.main import main
from tests.conftest import ROOT

DEMO = str(ROOT / "cells" / "demo_ur5e.yaml")
PICK = """task: pick_then_home
steps:
  - move: home
  - pick: {at: infeed, approach: 0.1, grip: {confirm: gripper_closed}}
  - move: home
on_error:
"""


def run_json(*argv: str) -> tuple[int, dict]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main([*argv, "--json"])
    return code, json.loads(out.getvalue())


def task(tmp_path, on_error: str) -> str:
    path = tmp_path / "t.yaml"
    path.write_text(PICK + on_error)
    return str(path)


def test_a_joint_move_from_a_part_resting_on_the_table_is_refused_by_name(tmp_path):
    """After the grip the block still rests on the table: a planned joint move home from
    there would drag it through the table; check names the on_error step and the state."""
    code, out = run_json("check", DEMO, task(tmp_path, "  - move: home\n"))
    assert code == 1 and not out["ok"]
    assert out["errors"] == [
        "on_error step 7 move 'home': from the end of step 4 grip 'infeed': start "
        "configuration in collision: part 'block' collides with fixture 'table' (-0.0 mm "
        "deep; must keep 2.0 mm)"
    ]
    row = out["steps"][-1]
    assert (row["index"], row["kind"], row["status"]) == (7, "move", "failed")


def test_lifting_first_makes_on_error_feasible_from_every_state(tmp_path):
    code, out = run_json("check", DEMO, task(tmp_path, "  - lift: 0.03\n  - move: home\n"))
    assert code == 0, out["errors"]
    rows = [(s["index"], s["kind"], s["status"], s["message"]) for s in out["steps"][-2:]]
    assert rows == [
        (7, "lift", "ok", "on_error: verified from 6 states the job can fail in"),
        (8, "move", "ok", "on_error: verified from 6 states the job can fail in"),
    ]


def test_an_on_error_line_out_of_reach_is_refused_from_every_state(tmp_path):
    code, out = run_json("check", DEMO, task(tmp_path, "  - lift: 1.5\n"))
    assert code == 1
    (error,) = out["errors"]
    assert error.startswith("on_error step 7 lift: from the start: ")
    assert error.endswith(" (and from 5 more states)")


def test_a_job_whose_on_error_cannot_run_is_refused_before_it_moves(tmp_path):
    pytest.importorskip("mujoco")
    code, out = run_json("dry-run", DEMO, task(tmp_path, "  - move: home\n"))
    assert code == 1
    assert out["result_code"] == 103  # planning failed
    assert out["result_text"].startswith("on_error step 7 move 'home': from the end of step 4 ")
    assert {s["status"] for s in out["steps"]} == {"not run"}
