"""Linear TCP moves (descend, linear, lift, retreat): the straight line from the start
pose to the goal pose, orientation by slerp, followed by inverse kinematics sample by
sample on one continuous branch.

Guarantees of :func:`plan_linear` (all positions in the world frame, m):

- every sample is an exact IK solution (FK-verified) of its pose on the line;
- consecutive samples stay on one branch: no joint moves more than ``max_joint_step_rad``
  between samples that are at most ``step_m`` / ``step_rad`` apart on the line;
- between consecutive samples the straight joint interpolation keeps the TCP within
  ``CHORD_TOLERANCE_M`` of the line (checked at the midpoint and subdivided until it
  holds), so a dense resampling stays well inside the 1 mm straightness budget;
- every sample keeps the singularity distances above the thresholds;
- the joint-space polyline is collision-checked conservatively.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.body import BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.planning.collision import Clearance, CollisionModel
from cellrunner.planning.kinematics import ArmKinematics, rotation_angle_rad

STEP_M = 0.005
STEP_RAD = np.radians(2.0)
CHORD_TOLERANCE_M = 0.0002
MAX_JOINT_STEP_RAD = np.radians(15.0)
MIN_SINGULARITY_ANGLE_DEG = 3.0
MIN_SHOULDER_DISTANCE_M = 0.02


@dataclass(frozen=True)
class LinearPath:
    """Joint samples ``q_rad`` (N x 6) along the TCP line from ``p_start_m`` to ``p_goal_m``
    (world), ``u`` (N) their fraction along the line, 0 to 1."""

    q_rad: np.ndarray
    u: np.ndarray
    p_start_m: np.ndarray
    p_goal_m: np.ndarray


def distance_to_segment_m(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points ``p`` (N x 3) from the segment a-b."""
    p = np.atleast_2d(p)
    ab = b - a
    n2 = float(ab @ ab)
    t = np.zeros(len(p)) if n2 == 0 else np.clip((p - a) @ ab / n2, 0.0, 1.0)
    return np.asarray(np.linalg.norm(p - (a + t[:, None] * ab), axis=1))


def quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of the rotation matrix ``R``."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(np.asarray(R, float)).as_quat(scalar_first=True))


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the unit quaternion ``q`` (w, x, y, z)."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_quat(np.asarray(q, float), scalar_first=True).as_matrix())


def slerp(q0: np.ndarray, q1: np.ndarray, u: float) -> np.ndarray:
    """Spherical interpolation between unit quaternions, the shorter way, ``u`` in [0, 1]."""
    from scipy.spatial.transform import Rotation, Slerp

    turn = Slerp([0.0, 1.0], Rotation.from_quat([q0, q1], scalar_first=True))
    return np.asarray(turn(u).as_quat(scalar_first=True))


def plan_linear(
    kinematics: ArmKinematics,
    collision: CollisionModel | None,
    q_start_rad: np.ndarray,
    T_world_tcp_goal: np.ndarray,
    *,
    min_singularity_angle_deg: float = MIN_SINGULARITY_ANGLE_DEG,
    min_shoulder_distance_m: float = MIN_SHOULDER_DISTANCE_M,
) -> LinearPath:
    """Joint samples moving the TCP in a straight line from FK(q_start) to the goal pose.

    Raises :class:`InfeasibleError` naming the reason and where along the line (mm from the
    start) it occurs: unreachable pose, branch flip, singularity or collision.
    """
    q0 = np.asarray(q_start_rad, float)
    T0 = kinematics.T_world_tcp(q0)
    T1 = np.asarray(T_world_tcp_goal, float)
    p0, p1 = T0[:3, 3], T1[:3, 3]
    length_m = float(np.linalg.norm(p1 - p0))
    from scipy.spatial.transform import Rotation, Slerp

    turn = Slerp([0.0, 1.0], Rotation.from_matrix([T0[:3, :3], T1[:3, :3]]))
    angle_rad = rotation_angle_rad(T0[:3, :3].T @ T1[:3, :3])
    n = max(1, int(np.ceil(max(length_m / STEP_M, angle_rad / STEP_RAD))))

    def pose(u: float) -> np.ndarray:
        T = np.eye(4)
        # most lines keep the tool's orientation: no interpolation to evaluate then
        T[:3, :3] = turn(u).as_matrix() if angle_rad > 1e-12 else T1[:3, :3]
        T[:3, 3] = p0 + u * (p1 - p0)
        return T

    def solve(u: float, q_prev: np.ndarray) -> np.ndarray:
        q = kinematics.ik_track(pose(u), q_prev)
        where = f"{u * length_m * 1000:.0f} mm along the {length_m * 1000:.0f} mm line"
        if q is None:
            raise InfeasibleError(
                Failure(
                    FailureKind.UNREACHABLE,
                    f"line leaves the workspace {where}: {kinematics.unreachable_reason(pose(u))}",
                )
            )
        jump = float(np.abs(q - q_prev).max())
        if jump > MAX_JOINT_STEP_RAD:
            joint = int(np.abs(q - q_prev).argmax()) + 1
            raise InfeasibleError(
                Failure(
                    FailureKind.SINGULARITY,
                    f"line needs a configuration flip {where} (joint {joint} jumps "
                    f"{np.degrees(jump):.0f} deg between samples)",
                )
            )
        reason = kinematics.singularity_distance(q).violation(
            min_singularity_angle_deg, min_shoulder_distance_m
        )
        if reason is not None:
            raise InfeasibleError(
                Failure(FailureKind.SINGULARITY, f"line passes near the {reason} {where}")
            )
        return q

    us, qs = [0.0], [q0]
    for k in range(1, n + 1):
        u = k / n
        qs_new, us_new = _refine(kinematics, solve, us[-1], qs[-1], u, solve(u, qs[-1]), p0, p1)
        us.extend(us_new)
        qs.extend(qs_new)
    q_path = np.array(qs)
    if collision is not None:
        _check_line_clear(collision, q_path, us, length_m)
    return LinearPath(q_path, np.array(us), p0.copy(), p1.copy())


def _check_line_clear(
    collision: CollisionModel, q_path: np.ndarray, us: list[float], length_m: float
) -> None:
    """Raise :class:`InfeasibleError` naming what blocks the line's samples ``q_path``
    (at fractions ``us`` of its ``length_m``) and where along it, if anything does."""
    result = collision.check_path(q_path)
    if not result.ok:
        u_hit = us[int(result.s_blocked or 0)]
        c = result.clearance
        blockers = (Blocker(c.b, c.distance_m), Blocker(c.a, c.distance_m)) if c is not None else ()
        detail = c.describe() if c is not None else "collision"
        raise InfeasibleError(
            Failure(
                FailureKind.COLLISION,
                f"{detail} {u_hit * length_m * 1000:.0f} mm along the line",
                blockers=blockers,
                fix=_line_fix(collision, q_path[-1], c),
            )
        )


def _line_fix(collision: CollisionModel, q_end: np.ndarray, c: Clearance | None) -> str:
    """The fix for a blocked line: when the blocking fixture is still within its clearance
    where the line ends, the line is likely meant to end there (a tight fit)."""
    from cellrunner.planning.blockers import fix_hint
    from cellrunner.planning.tight_fit import line_end_hint

    if c is not None and c.b.kind is BodyKind.FIXTURE and c.distance_m > -0.001:
        at_end = [v for v in collision.violations(q_end) if v.b.kind is BodyKind.FIXTURE]
        if any(v.b == c.b for v in at_end) and min(v.distance_m for v in at_end) > -0.001:
            return line_end_hint(sorted({v.b for v in at_end}), min(v.distance_m for v in at_end))
    return fix_hint("line", (c.b, c.a) if c is not None else ())


def _refine(
    kin: ArmKinematics,
    solve: Callable[[float, np.ndarray], np.ndarray],
    u_a: float,
    q_a: np.ndarray,
    u_b: float,
    q_b: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    depth: int = 0,
) -> tuple[list[np.ndarray], list[float]]:
    """Samples after (u_a, q_a) up to (u_b, q_b), subdividing until the joint-space midpoint
    keeps the TCP within CHORD_TOLERANCE_M of the line."""
    mid = kin.T_world_tcp((q_a + q_b) / 2)[:3, 3]
    if depth >= 8 or distance_to_segment_m(mid, p0, p1)[0] <= CHORD_TOLERANCE_M:
        return [q_b], [u_b]
    u_m = (u_a + u_b) / 2
    q_m = solve(u_m, q_a)
    qa, ua = _refine(kin, solve, u_a, q_a, u_m, q_m, p0, p1, depth + 1)
    qb, ub = _refine(kin, solve, u_m, q_m, u_b, q_b, p0, p1, depth + 1)
    return qa + qb, ua + ub
