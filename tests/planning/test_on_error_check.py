"""``check`` verifies a task's on_error steps from every state a failure can leave the
arm in (SPEC section 11): each one's row says from how many states it was verified, an
infeasible one is named with the state it fails from, and a job whose on_error cannot
run is refused like any infeasible job."""

from __future__ import annotations

import numpy as np
import pytest

from tests.planning.on_error_rig import DEMO, task
from tests.rig import main_json


def test_a_joint_move_from_a_part_resting_on_the_table_is_refused_by_name(tmp_path):
    """After the grip the block still rests on the table: a planned joint move home from
    there would drag it through the table; check names the on_error step and the state."""
    code, out = main_json("check", DEMO, task(tmp_path, "  - move: home\n"))
    assert code == 1 and not out["ok"]
    assert out["errors"] == [
        "on_error step 7 move 'home': from the end of step 4 grip 'infeed': start "
        "configuration in collision: part 'block' collides with fixture 'table' (-0.0 mm "
        "deep; must keep 2.0 mm)"
    ]
    row = out["steps"][-1]
    assert (row["index"], row["kind"], row["status"]) == (7, "move", "failed")


def test_lifting_first_makes_on_error_feasible_from_every_state(tmp_path):
    code, out = main_json("check", DEMO, task(tmp_path, "  - lift: 0.03\n  - move: home\n"))
    assert code == 0, out["errors"]
    rows = [(s["index"], s["kind"], s["status"], s["message"]) for s in out["steps"][-2:]]
    assert rows == [
        (7, "lift", "ok", "on_error: verified from 12 states the job can fail in"),
        (8, "move", "ok", "on_error: verified from 12 states the job can fail in"),
    ]


def test_an_on_error_line_out_of_reach_is_refused_from_every_state(tmp_path):
    code, out = main_json("check", DEMO, task(tmp_path, "  - lift: 1.5\n"))
    assert code == 1
    (error,) = out["errors"]
    assert error.startswith("on_error step 7 lift: from the start: ")
    assert error.endswith(" (and from 11 more states)")


def test_a_job_whose_on_error_cannot_run_is_refused_before_it_moves(tmp_path):
    code, out = main_json("dry-run", DEMO, task(tmp_path, "  - move: home\n"))
    assert code == 1
    assert out["result_code"] == 103  # planning failed
    assert out["result_text"].startswith("on_error step 7 move 'home': from the end of step 4 ")
    assert {s["status"] for s in out["steps"]} == {"not run"}


PROBE = """task: probe
steps:
  - move: home
  - approach: {to: pallet, distance: 0.05}
  - move_until_contact: {direction: [0, 0, -1], frame: world, speed: 0.01, force: 10, max_distance: MAX}
  - retreat: 0.05
  - move: home
on_error:
  - retreat: 0.05
  - move: home
"""


def test_on_error_retreats_from_where_a_guarded_line_touched(tmp_path):
    """The tool probes the table 58 mm below the approach; its line runs 80 mm, 22 mm into
    the table. on_error starts where the line touched, and its retreat may leave that
    contact (it was proved from the full travel, inside the table, and refused)."""
    path = tmp_path / "probe.yaml"
    path.write_text(PROBE.replace("MAX", "0.08"))
    code, out = main_json("check", DEMO, str(path), "--no-cache")
    assert code == 0, out["errors"]
    assert [s["status"] for s in out["steps"][-2:]] == ["ok", "ok"]

    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.job_plan import plan_job
    from cellrunner.planning.on_error import _starts
    from cellrunner.planning.world import CellWorld

    world = CellWorld(load_cell(DEMO))
    plan = plan_job(world, load_task(str(path), world.loaded), {}, world.q_home_rad).task_plan
    starts = {s.label: s for s in _starts(plan)}
    touch = starts["from the contact of step 3 move_until_contact"]
    assert "from the end of step 3 move_until_contact" not in starts
    # 58 mm down the line: the pads' lowest point on the table top, not 22 mm inside it
    drop_m = (
        world.kinematics.p_world_tcp(plan.rows[1].q_end_rad)[2]
        - (world.kinematics.p_world_tcp(touch.q_rad)[2])
    )
    assert drop_m == pytest.approx(0.058, abs=0.001)


def test_a_guarded_line_that_meets_nothing_is_refused(tmp_path):
    path = tmp_path / "probe.yaml"
    path.write_text(PROBE.replace("MAX", "0.04"))
    code, out = main_json("check", DEMO, str(path), "--no-cache")
    assert code == 1
    assert out["errors"] == [
        "step 3 move_until_contact: the guarded line meets nothing within its max_distance "
        "40 mm: at its end the tool is still 18.0 mm from fixture 'table', so the step would "
        "fail with no contact; fix: a longer max_distance (at least 58 mm), or move the frame "
        "it starts from"
    ]


def test_on_error_is_proved_from_the_middle_of_joint_moves_with_and_without_the_part(tmp_path):
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.job_plan import plan_job
    from cellrunner.planning.on_error import _starts
    from cellrunner.planning.world import CellWorld

    world = CellWorld(load_cell(DEMO))
    path = task(tmp_path, "  - lift: 0.03\n  - move: home\n")
    plan = plan_job(world, load_task(path, world.loaded), {}, world.q_home_rad).task_plan
    starts = {s.label: s for s in _starts(plan)}
    carried = starts["from the middle of step 6 move 'home'"]
    lost = starts["from the middle of step 6 move 'home', the part lost"]
    assert carried.part is not None and carried.part.name == "block" and lost.part is None
    assert np.array_equal(carried.q_rad, lost.q_rad)
    assert "from the middle of step 2 approach 'infeed'" in starts  # nothing carried: once
    assert "from the middle of step 2 approach 'infeed', the part lost" not in starts
