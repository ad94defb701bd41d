"""FK/IK round trips on every model with a mount and a TCP; Jacobian vs finite differences."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.kinematics import ArmKinematics, rotation_angle_rad

MOUNT = pose_matrix((0.3, -0.2, 0.9), (0, 20, 45))
TCP = pose_matrix((0.01, 0, 0.15), (0, 0, 30))
angles = st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6).map(np.array)


@pytest.mark.parametrize("model", sorted(ROBOTS))
@settings(max_examples=25, deadline=None)
@given(q=angles)
def test_ik_round_trip_returns_a_configuration_with_the_same_pose(model, q):
    kin = ArmKinematics(ROBOTS[model], MOUNT, TCP)
    T = kin.T_world_tcp(q)
    sd = kin.singularity_distance(q)
    if min(sd.wrist_deg, sd.elbow_deg) < 1.0 or sd.shoulder_m < 0.005:
        return  # branches merge at singularities; the pose test below still holds
    solutions = kin.ik_all(T, q)
    assert solutions, "a pose reached by FK must have an IK solution"
    for s in solutions:
        T2 = kin.T_world_tcp(s)
        assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < 1e-6
        assert rotation_angle_rad(T2[:3, :3].T @ T[:3, :3]) < 1e-6
        assert kin.within_limits(s)
    assert np.abs(solutions[0] - q).max() < 1e-5  # the nearest branch is the one we came from


def test_every_arm_ur_analytic_ik_solves_is_supported():
    import ur_analytic_ik

    solved = {
        n for n in dir(ur_analytic_ik) if hasattr(getattr(ur_analytic_ik, n), "forward_kinematics")
    }
    assert solved == set(ROBOTS)


@pytest.mark.parametrize("model", sorted(ROBOTS))
def test_flange_fk_matches_ur_analytic_ik(model):
    import ur_analytic_ik

    kin = ArmKinematics(ROBOTS[model], np.eye(4), np.eye(4))
    fk = getattr(ur_analytic_ik, model).forward_kinematics
    for q in np.random.default_rng(9).uniform(-2 * np.pi, 2 * np.pi, (40, 6)):
        assert np.allclose(kin.T_world_flange(q), fk(*q), atol=1e-10)


@pytest.mark.parametrize("model", sorted(ROBOTS))
def test_controller_rate_and_limits_per_generation(model):
    spec = ROBOTS[model]
    assert spec.rate_hz == (125.0 if model in ("ur3", "ur5", "ur10") else 500.0)
    assert len(spec.joint_speed_max_deg_s) == 6 and min(spec.joint_speed_max_deg_s) >= 120
    assert spec.joint_min_deg == (-360.0,) * 6 and spec.joint_max_deg == (360.0,) * 6
    assert 0.5 <= spec.reach_m <= 1.75 and 3 <= spec.payload_max_kg <= 30


@settings(max_examples=20, deadline=None)
@given(q=angles)
def test_jacobian_matches_finite_differences(q):
    kin = ArmKinematics(ROBOTS["ur5e"], MOUNT, TCP)
    J = kin.jacobian_tcp(q)
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        Tp, Tm = kin.T_world_tcp(q + dq), kin.T_world_tcp(q - dq)
        assert np.allclose((Tp[:3, 3] - Tm[:3, 3]) / (2 * h), J[:3, i], atol=1e-6)
        dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ kin.T_world_tcp(q)[:3, :3].T
        omega = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
        assert np.allclose(omega, J[3:, i], atol=1e-6)


def test_far_target_is_out_of_reach_with_numbers():
    kin = ArmKinematics(ROBOTS["ur5e"], pose_matrix((0, 0, 0.9)), pose_matrix((0, 0, 0.15)))
    with pytest.raises(
        InfeasibleError, match=r"out of reach \(1\.\d\d m from the shoulder, UR5e reach 0\.85 m\)"
    ):
        kin.ik_nearest(pose_matrix((1.9, 0.3, 1.0), (180, 0, 0)), np.zeros(6))


def test_ik_wraps_joints_towards_the_reference_within_limits():
    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), np.eye(4))
    q = np.array([5.5, -1.0, 1.2, -1.5, -1.4, -5.0])  # beyond +-pi, inside +-2pi
    assert np.allclose(kin.ik_nearest(kin.T_world_tcp(q), q), q, atol=1e-6)


def test_singularity_distances_name_the_wrist():
    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), np.eye(4))
    sd = kin.singularity_distance(np.array([0, -1.2, 1.2, -1.0, 0.01, 0]))
    assert sd.wrist_deg == pytest.approx(np.degrees(0.01))
    assert "wrist singularity" in sd.violation(3.0, 0.02)
    assert (
        kin.singularity_distance(np.radians([0, -90, 90, -90, -90, 0])).violation(3.0, 0.02) is None
    )


@pytest.mark.parametrize("model", sorted(ROBOTS))
def test_batched_tcp_positions_match_pinocchio_fk_per_sample(model):
    """The vectorized FK the verifier and the TCP cap use is the same FK, sample by sample."""
    kin = ArmKinematics(ROBOTS[model], MOUNT, TCP)
    q = np.random.default_rng(3).uniform(-6.2, 6.2, (300, 6))
    batched = kin.p_world_tcp_many(q)
    assert batched.shape == (300, 3)
    assert np.abs(batched - [kin.p_world_tcp(qi) for qi in q]).max() < 1e-12
    assert np.allclose(kin.p_world_tcp_many(q[0]), kin.p_world_tcp(q[0]), atol=1e-12)


@pytest.mark.parametrize("model", ["ur5e", "ur10e", "ur3e"])
def test_ik_at_home_on_a_turned_mount_finds_home_itself(model):
    """UR's usual home (tool straight down) sits on the edge of a branch's formula, where
    the closed-form solver's rounding dropped the branch: a straight line from home then
    needed a 150 deg shoulder flip."""
    kin = ArmKinematics(
        ROBOTS[model], pose_matrix((0, 0, 0.9), (0, 0, 180)), pose_matrix((0, 0, 0.15))
    )
    home = np.radians([0, -90, 90, -90, -90, 0])
    T = kin.T_world_tcp(home)
    assert np.allclose(kin.ik_all(T, home)[0], home, atol=1e-6)
    up = pose_matrix((0, 0, 0.004)) @ T
    assert np.max(np.abs(kin.ik_track(up, home) - home)) < np.radians(2.0)


def test_renamed_arms_are_their_originals():
    for new, old in (("ur7e", "ur5e"), ("ur12e", "ur10e")):
        a, b = ROBOTS[new], ROBOTS[old]
        assert a.arm == old and b.arm == old
        assert (a.d_m, a.a_m, a.joint_speed_max_deg_s) == (b.d_m, b.a_m, b.joint_speed_max_deg_s)


def test_the_elbow_is_never_wrapped_past_half_a_turn():
    """An elbow at -90.2 deg is the same arm as at 269.8, but reached the wrong way round:
    through the upper arm. From an elbow at +100 deg the nearest wrap is 269.8 (170 deg
    away, not 190); the branch must keep -90.2 (issue 24: that branch was chosen, and the
    hint blamed a pedestal the forearm met on its way round)."""
    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), np.eye(4))
    T = kin.T_world_tcp(np.radians([10, -100, -90.2, -80, 90, 0]))
    near = np.radians([10, -100, 100, -80, 90, 0])
    branches = kin.ik_all(T, near)
    assert branches and all(abs(q[2]) <= np.pi + 1e-9 for q in branches)
    assert any(
        np.allclose(np.degrees(q), [10, -100, -90.2, -80, 90, 0], atol=1e-3) for q in branches
    )
    tracked = kin.ik_track(T, near)
    assert tracked is not None and abs(tracked[2]) <= np.pi + 1e-9
