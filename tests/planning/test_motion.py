"""Linear moves stay straight, timing keeps every limit at every sample, and the verifier
refuses what breaks a rule (a whole task's plan: tests/planning/test_task_plan.py)."""

import numpy as np
import pytest

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.model.trajectory import Trajectory
from cellrunner.planning.cartesian import distance_to_segment_m, plan_linear
from cellrunner.planning.collision import CollisionModel
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.timing import MotionLimits, sample_measures, time_path
from cellrunner.planning.verify import verify_trajectory

SPEC = ROBOTS["ur5e"]
HOME = np.radians([180, -90, 90, -90, -90, 0])
TCP = pose_matrix((0, 0, 0.15))
TOOL = (Placed("gripper", Cylinder(0.04, 0.15), pose_matrix((0, 0, 0.075))),)
TABLE = Placed("table", Box((1.6, 1.6, 0.04)), pose_matrix((0, 0, -0.02)))
LIMITS = MotionLimits.from_cell(
    SPEC, joint_speed_deg_s=120, joint_accel_deg_s2=300, tcp_speed_mps=1.0
)


def down(x, y, z):
    return pose_matrix((x, y, z), (180, 0, 0))


@pytest.mark.parametrize("goal", [(0.45, -0.2, 0.05), (0.3, 0.3, 0.3), (0.55, 0.1, 0.1)])
def test_linear_move_is_straight_within_a_millimetre_after_timing(goal):
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    world = CollisionModel(kin, TOOL, [TABLE])
    q0 = kin.ik_nearest(down(0.4, -0.1, 0.35), HOME)
    path = plan_linear(kin, world, q0, down(*goal))
    timed = time_path(kin, path.q_rad, LIMITS.scaled(1.0, 0.5), SPEC.rate_hz)
    p = kin.p_world_tcp_many(timed.q_rad)
    assert distance_to_segment_m(p, path.p_start_m, path.p_goal_m).max() < 0.001
    assert np.allclose(p[-1], goal, atol=1e-6)


def test_linear_move_into_the_table_is_refused_naming_the_pair():
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    world = CollisionModel(kin, TOOL, [TABLE])
    q0 = kin.ik_nearest(down(0.4, -0.1, 0.2), HOME)
    with pytest.raises(InfeasibleError, match=r"tool 'gripper' .* fixture 'table'"):
        plan_linear(kin, world, q0, down(0.4, -0.1, -0.05))


def test_timing_keeps_limits_at_every_sample_and_ends_on_the_grid():
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    wp = np.radians(
        [[180, -90, 90, -90, -90, 0], [120, -60, 100, -80, -90, 40], [60, -100, 80, -90, -80, 0]]
    )
    timed = time_path(kin, wp, LIMITS, SPEC.rate_hz)
    assert np.allclose(timed.t_s, np.arange(len(timed.t_s)) / 500.0)
    assert np.array_equal(timed.q_rad[-1], wp[-1]) and np.array_equal(timed.q_rad[0], wp[0])
    v, a, tcp = sample_measures(kin, timed.q_rad, 500.0)
    assert (np.abs(v) <= LIMITS.joint_speed_rad_s).all()
    assert (np.abs(a) <= LIMITS.joint_accel_rad_s2).all()
    assert tcp.max() <= LIMITS.tcp_speed_mps
    assert np.abs(a).max(axis=0)[1] > 0.5 * LIMITS.joint_accel_rad_s2[1]  # time-optimal, not timid


def test_tcp_speed_cap_is_kept():
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    wp = np.radians([[180, -90, 90, -90, -90, 0], [100, -90, 90, -90, -90, 0]])
    slow = LIMITS.scaled(1.0, 0.1)
    _, _, tcp = sample_measures(kin, time_path(kin, wp, slow, 500.0).q_rad, 500.0)
    assert 0.5 * slow.tcp_speed_mps < tcp.max() <= slow.tcp_speed_mps


def test_toppra_failure_becomes_our_error(monkeypatch):
    import toppra.algorithm as algo

    monkeypatch.setattr(
        algo.TOPPRA, "compute_parameterization", lambda self, a, b: (None, None, None)
    )
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    with pytest.raises(InfeasibleError, match="time parameterization failed"):
        time_path(
            kin, np.radians([[0, -90, 90, -90, -90, 0], [30, -90, 90, -90, -90, 0]]), LIMITS, 500.0
        )


def _verify(q, **kw):
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    world = CollisionModel(kin, TOOL, [TABLE])
    traj = Trajectory(500.0, np.arange(len(q)) / 500.0, q)
    return verify_trajectory(
        traj,
        step_index=3,
        step_name="transfer",
        kinematics=kin,
        limits=LIMITS,
        collision=world,
        **kw,
    )


def test_verifier_refuses_a_jump_with_numbers():
    q = np.repeat(HOME[None], 10, axis=0)
    q[5:, 0] += 0.05
    with pytest.raises(
        InfeasibleError,
        match=r"step 3 transfer: shoulder_pan speed 1432\.4 deg/s exceeds the limit 114\.0 deg/s",
    ):
        _verify(q)


def test_verifier_refuses_a_discontinuity_and_a_wrong_rate():
    q = np.repeat(HOME[None], 3, axis=0)
    with pytest.raises(InfeasibleError, match=r"starts 5\.7296 deg away"):
        _verify(q, previous_q_rad=HOME + [0.1, 0, 0, 0, 0, 0])
    kin = ArmKinematics(SPEC, np.eye(4), TCP)
    with pytest.raises(InfeasibleError, match="125 Hz"):
        verify_trajectory(
            Trajectory(125.0, np.arange(3) / 125.0, q),
            step_index=1,
            step_name="x",
            kinematics=kin,
            limits=LIMITS,
            collision=CollisionModel(kin),
        )
