"""Planning failures name what blocks them: the fixture and link, each IK branch's
reason, and a fix."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.blockers import every_branch_collides, unreachable
from cellrunner.planning.collision import Clearance, CollisionModel
from cellrunner.planning.joint_path import plan_joint_path
from cellrunner.planning.kinematics import ArmKinematics

TOOL = (Placed("gripper", Cylinder(0.04, 0.15), pose_matrix((0, 0, 0.075))),)
DOWN = (180.0, 0.0, 0.0)
NEAR = np.radians([180, -90, 90, -90, -90, 0])


def _kinematics() -> ArmKinematics:
    return ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_matrix((0, 0, 0.15)))


def _split_world() -> CollisionModel:
    """Two tall walls in the plane y = 0, in front of and behind the base, leaving only a
    gap around the base too narrow for the arm: the two sides cannot be joined."""
    fixtures = [
        Placed("table", Box((1.6, 1.6, 0.04)), pose_matrix((0, 0, -0.02))),
        Placed("conveyor", Box((1.3, 0.03, 2.0)), pose_matrix((0.8, 0.0, 1.0))),
        Placed("guard", Box((1.3, 0.03, 2.0)), pose_matrix((-0.8, 0.0, 1.0))),
    ]
    return CollisionModel(_kinematics(), TOOL, fixtures)


def _free_branch(world: CollisionModel, xyz) -> np.ndarray:
    return next(
        q for q in world.kinematics.ik_all(pose_matrix(xyz, DOWN), NEAR) if world.is_valid(q)
    )


def test_failed_search_names_the_fixtures_and_links_in_the_way():
    world = _split_world()
    a, b = _free_branch(world, (0.3, -0.55, 0.06)), _free_branch(world, (0.3, 0.55, 0.06))
    with pytest.raises(InfeasibleError) as caught:
        plan_joint_path(world, a, b, time_budget_s=0.5)
    message = str(caught.value)
    assert message.startswith("no collision-free joint path found within 0.5 s (RRTConnect: ")
    assert (
        "blocked by fixture 'guard' (upper_arm in " in message
        or "blocked by fixture 'conveyor' (" in message
    )
    assert " of 60 sampled states" in message
    assert "fix: move fixture '" in message and "away from the arm's way" in message
    assert {"fixture 'guard'", "fixture 'conveyor'"} <= set(caught.value.blockers)
    assert "upper_arm" in caught.value.blockers


def test_every_branch_colliding_lists_each_branch_and_the_fixture():
    kin = _kinematics()
    target = pose_matrix((0.45, 0.0, 0.3), DOWN)
    # a slab through the wrist's whole neighbourhood: every branch reaching the pose hits it
    world = CollisionModel(
        kin, TOOL, [Placed("conveyor", Box((0.5, 0.5, 0.05)), pose_matrix((0.45, 0.0, 0.62)))]
    )
    assert all(not world.is_valid(q) for q in kin.ik_all(target, NEAR))
    error = every_branch_collides("step 2 approach 'x'", kin, world, target, NEAR)
    message = str(error)
    branches = len(kin.ik_all(target, NEAR))
    assert message.startswith(
        f"step 2 approach 'x': every IK branch collides, {branches} of {branches} "
        "with fixture 'conveyor' (mostly the "
    )
    assert message.count("elbow up") + message.count("elbow down") == branches
    assert "in fixture 'conveyor'" in message and "mm deep" in message
    assert message.endswith(
        "fix: move the frame away from fixture 'conveyor', or approach from another "
        "direction (turn the frame's rpy)"
    )
    assert error.blockers[0] == "fixture 'conveyor'"


def test_joint_range_refusal_names_the_joint_and_its_range():
    spec = ROBOTS["ur5e"]
    kin = ArmKinematics(spec, np.eye(4), pose_matrix((0, 0, 0.15)))
    target = pose_matrix((0.0, 0.45, 0.3), DOWN)  # straight along +Y: q1 near +90 or -90 + 180
    kin.q_min_rad = kin.q_min_rad.copy()
    kin.q_max_rad = kin.q_max_rad.copy()
    kin.q_min_rad[0], kin.q_max_rad[0] = (
        np.radians(-10),
        np.radians(10),
    )  # a narrow joint_range on the base
    assert kin.ik_all(target, NEAR) == []
    error = unreachable("step 2 approach 'y'", kin, CollisionModel(kin, TOOL, []), target, NEAR)
    message = str(error)
    assert "branches tried: " in message
    assert "joint 1 at " in message and "is outside its range [-10, 10] (joint_range)" in message
    assert message.endswith(
        "fix: move the frame toward the robot, or widen robot.joint_range if a joint limit refuses it"
    )


def test_out_of_reach_in_metres_that_were_meant_as_mm_says_so():
    kin = _kinematics()
    message = kin.unreachable_reason(pose_matrix((1253.0, 30.0, 150.0), DOWN))
    assert message.startswith("out of reach (1262.30 m")
    assert (
        "m from the shoulder, UR5e reach 0.85 m): did you mean mm? (read as mm, 1262.30 m is 1.262 m)"
        in message
    )
    assert message.endswith(" m is 1.262 m)")


def test_the_mm_hint_is_data_and_the_approach_fix_replaces_it():
    kin = _kinematics()
    far = pose_matrix((1253.0, 30.0, 150.0), DOWN)
    reason, hint = kin.unreachable_why(far)
    assert reason.startswith("out of reach (") and hint.startswith(": did you mean mm?")
    assert kin.unreachable_why(pose_matrix((1.2, 0.0, 0.2), DOWN))[1] == ""  # merely far
    scene = CollisionModel(kin, TOOL, [])
    frame = unreachable("step 2 approach 'y'", kin, scene, far, NEAR).failure
    assert frame.reason == reason + hint and "frame's xyz in metres" in frame.fix
    approach = unreachable("step 2 approach 'y'", kin, scene, far, NEAR, approach_m=50.0).failure
    assert approach.reason == reason and "did you mean 50 mm" in approach.fix


@pytest.mark.parametrize(
    "distance_m, required_m, expected",
    [
        (
            0.00204,
            0.0021,
            "upper_arm is too close to fixture 'wall' (2.04 mm apart, 0.06 mm short of the 2.1 mm it must keep)",
        ),
        (
            0.002095,
            0.0021,
            "upper_arm is too close to fixture 'wall' (2.095 mm apart, 0.005 mm short of the 2.1 mm it must keep)",
        ),
        (-0.003, 0.002, "upper_arm collides with fixture 'wall' (3.0 mm deep; must keep 2.0 mm)"),
        (  # a contact allowance never reads as a clearance below zero (issue 33)
            -0.0009,
            -0.0008,
            "upper_arm presses 0.90 mm into fixture 'wall', 0.10 mm more than the 0.80 mm it may",
        ),
    ],
)
def test_clearance_message_never_reads_as_no_shortfall(distance_m, required_m, expected):
    assert Clearance(distance_m, required_m, "upper_arm", "fixture 'wall'").describe() == expected
