"""change_tool: planning swaps the TCP (and geometry) at the change; the job runs in the
twin, the changer's lock confirmed by its locked input."""

from __future__ import annotations

import numpy as np
import pytest

from tests.cells.two_tools import CELL, TASK, TOUCH
from tests.rig import dry_run


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("tools")
    (d / "c.yaml").write_text(CELL)
    (d / "t.yaml").write_text(TASK)
    (d / "touch.yaml").write_text(TOUCH)
    (d / "touch_jaws.yaml").write_text(
        TOUCH.replace("  - change_tool: cup\n", "").replace("  - change_tool: jaws\n", "")
    )
    return d / "c.yaml", d / "t.yaml"


def test_change_tool_expands_and_plans_with_the_new_tcp(files):
    from cellrunner.model.expand import expand, frame_pose
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.task_plan import plan_task
    from cellrunner.planning.world import CellWorld

    cell = load_cell(files[0])
    steps = expand(load_task(files[1], cell), cell.cell, {})
    assert [s.kind for s in steps[1:9]] == [
        "approach",
        "descend",
        "tool_unlock",
        "retreat",
        "approach",
        "descend",
        "tool_lock",
        "retreat",
    ]
    world = CellWorld(cell)
    plan = plan_task(world, steps, world.q_home_rad)
    assert plan.ok, plan.errors
    # parking the cup: its descend (planned with the cup mounted) ends with the cup's TCP
    # (0.22 m) on the rack frame; the jaws' TCP (0.15 m) would be 7 cm above it
    park = plan.rows[11]
    assert (park.step.kind, park.step.name) == ("descend", "rack[cup]")
    rack = frame_pose(cell.cell, "rack_cup")[:3, 3]
    q = park.q_end_rad
    assert np.allclose(world.with_tool("cup").kinematics.T_world_tcp(q)[:3, 3], rack, atol=1e-4)
    assert np.allclose(world.kinematics.T_world_tcp(q)[:3, 3], rack + [0, 0, 0.07], atol=1e-4)
    assert park.world.loaded.cell.tool.gripper.kind == "vacuum"
    # the rack approach after the unlock carries no tool geometry, the one after the lock the cup's
    assert [p.name for p in plan.rows[5].world.tool] == []
    assert {p.name for p in plan.rows[9].world.tool} == {"gripper", "cup0"}


def test_change_tool_job_runs_in_the_twin(files):
    out = dry_run(*files)
    assert out["result_code"] == 0, out
    assert len(out["steps"]) == 19 and all(s["status"] == "ok" for s in out["steps"])


def test_the_twin_swaps_the_tool_physically(files):
    """The cup, mounted by the change, meets the table where its TCP says; without the
    change the jaws would meet it before the frame, and check knows it from the jaws'
    geometry."""
    cell = files[0]
    out = dry_run(cell, cell.parent / "touch.yaml")
    assert out["result_code"] == 0, out
    out = dry_run(cell, cell.parent / "touch_jaws.yaml")
    # the jaws' pads would hit the table before the frame: check refuses it before it moves
    assert out["result_code"] == 103
    assert out["result_text"].startswith("step 3 insert 'touch': the tool meets fixture 'table' ")
    assert " mm before frame 'touch'" in out["result_text"]


def test_a_second_jaw_gripper_after_the_change_grips_with_its_own_io(tmp_path):
    """The twin's jaws take the mounted tool's valve, sensor, stroke and TCP."""
    from tests.cells.two_tools import TWO_JAWS, WIDE_PICK

    (tmp_path / "c.yaml").write_text(TWO_JAWS)
    (tmp_path / "t.yaml").write_text(WIDE_PICK)
    out = dry_run(tmp_path / "c.yaml", tmp_path / "t.yaml")
    assert out["result_code"] == 0, out
    assert out["parts_end_m"]["block"] == pytest.approx([0.50, 0.05, 0.93], abs=0.003)
