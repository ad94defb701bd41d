"""Forward and inverse kinematics of a UR arm from its DH table, as the controller does.

Poses are UR poses ``p[x, y, z, rx, ry, rz]``: position in m and a rotation vector in rad,
of the TCP in the controller's base frame. ``T_base_flange`` is DH frame 6 (tool0); the
TCP is ``T_base_flange @ T_flange_tcp``. Inverse kinematics is numeric (damped least
squares from a seed), which is what ``get_inverse_kin(x, qnear)`` and ``movel`` need:
the solution nearest the seed.
"""

from __future__ import annotations

import math

import numpy as np

from cellrunner.model.robots import RobotSpec


def rotvec_to_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis * angle, rad), Rodrigues' formula."""
    rv = np.asarray(rv, dtype=float)
    theta = float(np.linalg.norm(rv))
    if theta < 1e-12:
        return np.eye(3)
    k = rv / theta
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.asarray(np.eye(3) + math.sin(theta) * K + (1 - math.cos(theta)) * (K @ K))


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix; angle in [0, pi]."""
    cos_t = max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))
    theta = math.acos(cos_t)
    if theta < 1e-9:
        return np.zeros(3)
    if math.pi - theta < 1e-6:
        # near pi: axis from the largest diagonal entry of (R + I) / 2
        M = (R + np.eye(3)) / 2.0
        i = int(np.argmax(np.diag(M)))
        axis = M[:, i] / math.sqrt(max(M[i, i], 1e-12))
        return axis / np.linalg.norm(axis) * theta
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w / (2.0 * math.sin(theta)) * theta


def pose_to_matrix(pose: np.ndarray) -> np.ndarray:
    """4x4 transform of a UR pose ``[x, y, z, rx, ry, rz]``."""
    pose = np.asarray(pose, dtype=float)
    T = np.eye(4)
    T[:3, :3] = rotvec_to_matrix(pose[3:6])
    T[:3, 3] = pose[:3]
    return T


def matrix_to_pose(T: np.ndarray) -> np.ndarray:
    """UR pose ``[x, y, z, rx, ry, rz]`` of a 4x4 transform."""
    return np.concatenate([T[:3, 3], matrix_to_rotvec(T[:3, :3])])


class Kinematics:
    """FK, Jacobian and numeric IK of one arm with a settable TCP offset (flange -> TCP)."""

    def __init__(self, spec: RobotSpec) -> None:
        self.spec = spec
        self._d = np.array(spec.d_m, dtype=float)
        self._a = np.array(spec.a_m, dtype=float)
        self._alpha = np.array(spec.alpha_rad, dtype=float)
        self.T_flange_tcp = np.eye(4)

    def set_tcp(self, tcp_pose: np.ndarray) -> None:
        """Set the TCP offset, a UR pose of the TCP in the flange frame."""
        self.T_flange_tcp = pose_to_matrix(tcp_pose)

    def flange(self, q_rad: np.ndarray) -> np.ndarray:
        """``T_base_flange`` (4x4) at joint angles ``q_rad``."""
        T = np.eye(4)
        for i in range(6):
            ct, st = math.cos(q_rad[i]), math.sin(q_rad[i])
            ca, sa = math.cos(self._alpha[i]), math.sin(self._alpha[i])
            A = np.array(
                [
                    [ct, -st * ca, st * sa, self._a[i] * ct],
                    [st, ct * ca, -ct * sa, self._a[i] * st],
                    [0.0, sa, ca, self._d[i]],
                    [0.0, 0.0, 0.0, 1.0],
                ]
            )
            T = T @ A
        return T

    def tcp(self, q_rad: np.ndarray, T_flange_tcp: np.ndarray | None = None) -> np.ndarray:
        """``T_base_tcp`` (4x4); ``T_flange_tcp`` defaults to the active TCP offset."""
        return np.asarray(
            self.flange(q_rad) @ (self.T_flange_tcp if T_flange_tcp is None else T_flange_tcp)
        )

    def tcp_pose(self, q_rad: np.ndarray) -> np.ndarray:
        """Active TCP as a UR pose in the base frame."""
        return matrix_to_pose(self.tcp(q_rad))

    def jacobian(self, q_rad: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        """6x6 geometric Jacobian of the TCP (rows: v_xyz m/s, w_xyz rad/s, base frame)."""
        T0 = self.tcp(q_rad)
        J = np.zeros((6, 6))
        for j in range(6):
            dq = np.array(q_rad, dtype=float)
            dq[j] += eps
            T1 = self.tcp(dq)
            J[:3, j] = (T1[:3, 3] - T0[:3, 3]) / eps
            J[3:, j] = matrix_to_rotvec(T1[:3, :3] @ T0[:3, :3].T) / eps
        return J

    def inverse(
        self,
        T_base_tcp: np.ndarray,
        q_seed_rad: np.ndarray,
        iterations: int = 60,
        tol_m: float = 1e-7,
        tol_rad: float = 1e-6,
    ) -> np.ndarray | None:
        """Joint angles reaching ``T_base_tcp`` nearest ``q_seed_rad``; None when it fails."""
        q = np.array(q_seed_rad, dtype=float)
        damping = 1e-4
        for _ in range(iterations):
            T = self.tcp(q)
            e = np.concatenate(
                [T_base_tcp[:3, 3] - T[:3, 3], matrix_to_rotvec(T_base_tcp[:3, :3] @ T[:3, :3].T)]
            )
            if np.linalg.norm(e[:3]) < tol_m and np.linalg.norm(e[3:]) < tol_rad:
                return q
            J = self.jacobian(q)
            step = J.T @ np.linalg.solve(J @ J.T + damping * np.eye(6), e)
            norm = float(np.linalg.norm(step))
            if norm > 0.5:  # keep each Newton step small so we stay on the seed's branch
                step *= 0.5 / norm
            q = q + step
        return None
