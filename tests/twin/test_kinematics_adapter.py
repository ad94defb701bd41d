"""The virtual controller's kinematics is the planner's: UR poses over ArmKinematics."""

from __future__ import annotations

import numpy as np

from cellrunner.model.robots import ROBOTS
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.twin.kinematics import Kinematics, matrix_to_pose, pose_to_matrix

TCP_POSE = np.array([0.01, 0.0, 0.15, 0.0, 0.0, 0.3])
Q = np.array([0.1, -1.2, 1.3, -1.6, -1.5, 0.3])


def test_twin_fk_is_the_planners_fk():
    twin = Kinematics(ROBOTS["ur5e"])
    twin.set_tcp(TCP_POSE)
    arm = ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_to_matrix(TCP_POSE))
    np.testing.assert_allclose(twin.tcp(Q), arm.T_world_tcp(Q), atol=1e-12)
    np.testing.assert_allclose(twin.flange(Q), arm.T_world_flange(Q), atol=1e-12)
    np.testing.assert_allclose(pose_to_matrix(twin.tcp_pose(Q)), arm.T_world_tcp(Q), atol=1e-12)


def test_twin_inverse_keeps_the_seeds_branch_and_turn():
    twin = Kinematics(ROBOTS["ur5e"])
    twin.set_tcp(TCP_POSE)
    for seed in (Q, Q + [0, 0, 0, 0, 0, 2 * np.pi]):
        q = twin.inverse(twin.tcp(seed + 0.01), seed)
        assert q is not None
        np.testing.assert_allclose(q, seed + 0.01, atol=1e-9)
    assert twin.inverse(pose_to_matrix([3.0, 0, 0, 0, 0, 0]), Q) is None


def test_twin_jacobian_matches_finite_differences():
    twin = Kinematics(ROBOTS["ur5e"])
    twin.set_tcp(TCP_POSE)
    J = twin.jacobian(Q)
    T0 = twin.tcp(Q)
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = 1e-7
        T1 = twin.tcp(Q + dq)
        np.testing.assert_allclose(J[:3, j], (T1[:3, 3] - T0[:3, 3]) / 1e-7, atol=1e-5)
        w = matrix_to_pose(np.block([[T1[:3, :3] @ T0[:3, :3].T, np.zeros((3, 1))], [0, 0, 0, 1]]))
        np.testing.assert_allclose(J[3:, j], w[3:] / 1e-7, atol=1e-5)
