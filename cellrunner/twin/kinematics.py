"""The virtual controller's view of the arm's kinematics: UR poses over
:class:`cellrunner.planning.kinematics.ArmKinematics`.

Poses are UR poses ``p[x, y, z, rx, ry, rz]``: position in m and a rotation vector in rad,
of the TCP in the controller's base frame. ``T_base_flange`` is DH frame 6 (tool0); the
TCP is ``T_base_flange @ T_flange_tcp``. Forward kinematics and the Jacobian are
pinocchio's, inverse kinematics is ur-analytic-ik's closed form; ``inverse`` keeps the
branch nearest the seed, which is what ``get_inverse_kin(x, qnear)`` and ``movel`` need.

Rotation vectors go through pinocchio's exp/log maps: the controller converts poses at
500 Hz and they cost well under a microsecond (scipy's ``Rotation.from_matrix`` costs
about 50).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from cellrunner.model.geometry import invert
from cellrunner.model.robots import RobotSpec
from cellrunner.planning.kinematics import ArmKinematics


def rotvec_to_matrix(rv_rad: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis * angle, rad)."""
    return np.asarray(pin.exp3(np.asarray(rv_rad, dtype=float)))


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix; angle in [0, pi]."""
    return np.asarray(pin.log3(np.asarray(R, dtype=float)))


def pose_to_matrix(pose: np.ndarray) -> np.ndarray:
    """4x4 transform of a UR pose ``[x, y, z, rx, ry, rz]``."""
    pose = np.asarray(pose, dtype=float)
    T = np.eye(4)
    T[:3, :3] = pin.exp3(pose[3:6])
    T[:3, 3] = pose[:3]
    return T


def matrix_to_pose(T: np.ndarray) -> np.ndarray:
    """UR pose ``[x, y, z, rx, ry, rz]`` of a 4x4 transform."""
    return np.concatenate([T[:3, 3], pin.log3(np.asarray(T[:3, :3], dtype=float))])


class Kinematics:
    """FK, Jacobian and IK of one arm in its base frame with a settable TCP offset
    (flange -> TCP)."""

    def __init__(self, spec: RobotSpec) -> None:
        self.spec = spec
        self.T_flange_tcp = np.eye(4)
        self._arm = ArmKinematics(spec, np.eye(4), self.T_flange_tcp)

    def set_tcp(self, tcp_pose: np.ndarray) -> None:
        """Set the TCP offset, a UR pose of the TCP in the flange frame."""
        self.T_flange_tcp = pose_to_matrix(tcp_pose)
        self._arm = ArmKinematics(self.spec, np.eye(4), self.T_flange_tcp)

    def flange(self, q_rad: np.ndarray) -> np.ndarray:
        """``T_base_flange`` (4x4) at joint angles ``q_rad``."""
        return self._arm.T_world_flange(q_rad)

    def tcp(self, q_rad: np.ndarray, T_flange_tcp: np.ndarray | None = None) -> np.ndarray:
        """``T_base_tcp`` (4x4); ``T_flange_tcp`` defaults to the active TCP offset."""
        if T_flange_tcp is None:
            return self._arm.T_world_tcp(q_rad)
        return np.asarray(self._arm.T_world_flange(q_rad) @ T_flange_tcp)

    def tcp_pose(self, q_rad: np.ndarray) -> np.ndarray:
        """Active TCP as a UR pose in the base frame."""
        return matrix_to_pose(self._arm.T_world_tcp(q_rad))

    def jacobian(self, q_rad: np.ndarray) -> np.ndarray:
        """6x6 geometric Jacobian of the TCP (rows: v_xyz m/s, w_xyz rad/s, base frame)."""
        return self._arm.jacobian_tcp(q_rad)

    def inverse(
        self, T_base_tcp: np.ndarray, q_seed_rad: np.ndarray, iterations: int = 60
    ) -> np.ndarray | None:
        """Joint angles reaching ``T_base_tcp`` nearest ``q_seed_rad`` (each joint within a
        half turn of the seed); None when the pose is unreachable. ``iterations`` is kept
        for the callers of the former numeric solver; the closed form needs none."""
        del iterations
        T_base_flange = np.asarray(T_base_tcp, dtype=float) @ invert(self.T_flange_tcp)
        seed = np.asarray(q_seed_rad, dtype=float)
        q = _nearest(self._arm.solve_flange(T_base_flange, search_dropped=False), seed)
        if q is None or float(np.abs(q - seed).max()) > NEAR_SEED_RAD:
            # the seed's branch may be one the solver dropped at this pose: search again
            q = _nearest(self._arm.solve_flange(T_base_flange), seed)
        return q


#: a branch this close to the seed (largest joint difference, rad) is the seed's own; a
#: 500 Hz step moves a joint far less
NEAR_SEED_RAD = 0.25


def _nearest(raw: list[np.ndarray], seed: np.ndarray) -> np.ndarray | None:
    """The branch nearest ``seed`` (largest joint difference), each joint shifted by
    multiples of 2 pi to be nearest the seed; None when there is none."""
    if not raw:
        return None
    candidates = np.array(raw)
    candidates += 2 * np.pi * np.round((seed - candidates) / (2 * np.pi))
    return np.asarray(candidates[int(np.argmin(np.abs(candidates - seed).max(axis=1)))])
