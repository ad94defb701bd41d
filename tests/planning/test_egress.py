"""A job that starts with the gripper down at a pick or place leaves along the tool first
(cellrunner.planning.egress), on the arm's own plan, and only then."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cellrunner.model import geometry
from cellrunner.model.expand import expand, frame_pose
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.step import StepKind
from cellrunner.planning.egress import corridors, egress_pose
from cellrunner.planning.task_plan import plan_task
from cellrunner.planning.world import CellWorld
from tests.conftest import DEMO_CELL, PICK_PLACE, ROOT


@pytest.fixture(scope="module")
def demo():
    cell = load_cell(DEMO_CELL)
    steps = expand(load_task(PICK_PLACE, cell), cell.cell, {"slot": 4})
    return cell, steps


def _target(steps, n=0):
    """The n-th pick or place target of ``steps`` and its approach distance."""
    pairs = [
        (b, s)
        for b, s in itertools.pairwise(steps)
        if b.kind is StepKind.APPROACH and s.kind is StepKind.DESCEND
    ]
    return pairs[n][1].T_world_tcp, pairs[n][0].args.distance


def test_in_a_pick_it_goes_back_to_the_approach_height(demo):
    cell, steps = demo
    T, depth = _target(steps)
    inside = T @ geometry.pose_matrix((0.01, -0.005, -0.03))  # 3 cm above the grip, a bit off
    found = egress_pose(corridors(steps, cell.cell), inside)
    assert found is not None
    pose, why = found
    np.testing.assert_allclose(pose[:3, :3], inside[:3, :3], atol=1e-12)  # no turn
    # straight back along the tool: to the approach height, the same offset across
    in_target = geometry.invert(T) @ pose
    np.testing.assert_allclose(in_target[:3, 3], [0.01, -0.005, -depth], atol=1e-9)
    assert "70 mm inside" in why and "infeed" in why


def test_in_a_place_of_this_job_too(demo):
    cell, steps = demo
    T, depth = _target(steps, n=1)  # the place at slot 4
    found = egress_pose(corridors(steps, cell.cell), T)
    assert found is not None and f"{round(depth * 1000)} mm inside" in found[1]


@pytest.mark.parametrize(
    "where",
    [
        "home",
        "at the approach pose",
        "6 cm off the axis",
        "tilted 45 deg",
        "3 cm past the target",
    ],
)
def test_anywhere_else_it_does_not(demo, where):
    cell, steps = demo
    T, depth = _target(steps)
    world = CellWorld(cell)
    pose = {
        "home": world.kinematics.T_world_tcp(world.q_home_rad),
        "at the approach pose": T @ geometry.pose_matrix((0, 0, -depth)),
        "6 cm off the axis": T @ geometry.pose_matrix((0.06, 0, -0.05)),
        "tilted 45 deg": T @ geometry.pose_matrix((0, 0, -0.05), (45, 0, 0)),
        "3 cm past the target": T @ geometry.pose_matrix((0, 0, 0.03)),
    }[where]
    assert egress_pose(corridors(steps, cell.cell), pose) is None


def test_a_task_without_picks_leaves_a_resting_part_the_same_way():
    """``home`` after an e-stop at the infeed: the block rests there (the cell's parts)."""
    cell = load_cell(DEMO_CELL)
    steps = expand(load_task(ROOT / "tasks" / "home.yaml", cell), cell.cell, {})
    inside = frame_pose(cell.cell, "infeed") @ geometry.pose_matrix((0, 0, -0.02))
    found = egress_pose(corridors(steps, cell.cell), inside)
    assert found is not None and "80 mm inside block's infeed" in found[1]


def test_the_plan_leaves_along_the_tool_then_moves_on(demo):
    """Planned from inside the pick, the first move's path starts with a straight line
    back along the tool to the approach height (the TCP's path: straight, the tool's
    orientation kept), ends where the move from there ends, and is verified."""
    cell, steps = demo
    world = CellWorld(cell)
    T, depth = _target(steps)
    kin = world.kinematics
    q_grip = kin.ik_all(T, world.q_home_rad)[0]
    plan = plan_task(world, steps, q_grip)
    assert plan.ok, plan.errors
    first = plan.rows[0]
    assert first.step.kind is StepKind.MOVE and "leaves along the tool first" in first.message
    q = first.approved.trajectory.q_rad
    p = kin.p_world_tcp_many(q)
    rise = (geometry.invert(T)[:3, :3] @ (p - T[:3, 3]).T).T  # in the target's axes
    # the first part: straight up the target's -Z, no sideways drift, to the approach height
    up = np.flatnonzero(rise[:, 2] <= -depth + 1e-3)[0]
    assert up > 10
    assert np.abs(rise[:up, :2]).max() < 1e-3


def test_from_home_the_plan_is_unchanged(demo):
    cell, steps = demo
    world = CellWorld(cell)
    plan = plan_task(world, steps, world.q_home_rad)
    assert plan.ok and all("leaves along the tool" not in (r.message or "") for r in plan.rows)
