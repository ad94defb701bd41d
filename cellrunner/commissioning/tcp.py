"""The tool centre point from poses about one fixed point (the "4-point" TCP method): the
TCP touches the same point from several orientations, so that for every flange pose i
``R_i @ t + p_i = c`` with ``t`` the TCP in the flange frame and ``c`` the point in the
world. Solved by least squares; its conditioning decides whether the poses are varied
enough."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cellrunner.errors import CellrunnerError

#: fewer poses than this do not overdetermine the 6 unknowns well
MIN_POSES = 4
#: a pose turned less than this from one already taken adds nothing (deg)
MIN_POSE_ANGLE_DEG = 15.0
#: smallest / largest singular value of the stacked system below which the TCP is not
#: observable along some direction (the poses turn about one axis only)
MIN_CONDITIONING = 0.1


class TcpError(CellrunnerError):
    """The poses cannot determine the TCP (exit 1: take other poses)."""


@dataclass(frozen=True)
class TcpSolution:
    tcp_m: np.ndarray  # the TCP in the flange frame, m
    point_m: np.ndarray  # the fixed point, world frame, m
    residuals_m: np.ndarray  # per pose, distance of its TCP from the point, m
    conditioning: float

    @property
    def rms_m(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_m**2)))


def too_alike(T_world_flange: np.ndarray, taken: list[np.ndarray]) -> str | None:
    """Why a new pose adds too little next to ``taken`` (None when it is fine)."""
    for i, T in enumerate(taken):
        R = T[:3, :3].T @ T_world_flange[:3, :3]
        angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))
        if angle < MIN_POSE_ANGLE_DEG:
            return (
                f"this pose is turned only {angle:.1f} deg from pose {i + 1}; turn the tool at "
                f"least {MIN_POSE_ANGLE_DEG:g} deg from every pose taken"
            )
    return None


def solve_tcp(T_world_flange: list[np.ndarray]) -> TcpSolution:
    """The least-squares TCP of poses whose TCPs all touch one point."""
    if len(T_world_flange) < MIN_POSES:
        raise TcpError(f"{len(T_world_flange)} poses; the TCP needs at least {MIN_POSES}")
    A = np.vstack([np.hstack([T[:3, :3], -np.eye(3)]) for T in T_world_flange])
    b = -np.concatenate([T[:3, 3] for T in T_world_flange])
    singular = np.linalg.svd(A, compute_uv=False)
    conditioning = float(singular[-1] / singular[0])
    if conditioning < MIN_CONDITIONING:
        raise TcpError(
            f"the poses turn the tool about too few axes (conditioning {conditioning:.3f} < "
            f"{MIN_CONDITIONING:g}); tilt it about another axis as well"
        )
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    t, c = x[:3], x[3:]
    residuals = np.array([np.linalg.norm(T[:3, :3] @ t + T[:3, 3] - c) for T in T_world_flange])
    return TcpSolution(t, c, residuals, conditioning)
