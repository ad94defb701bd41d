"""Time parameterization (TOPP-RA) of joint paths and resampling at the controller rate.

A path is a polyline of joint waypoints (rad). It is densified (no joint moves more than
``DENSIFY_STEP_RAD`` between points), fitted with a cubic spline in the cumulative
joint-space distance ``s`` and time-optimally parameterized by TOPP-RA under

- joint speed limits x margin (rad/s),
- joint acceleration limits x margin (rad/s^2),
- the TCP speed cap x margin (m/s), as a path-varying joint-velocity constraint: with
  ``v(s) = |J_p(q(s)) q'(s)|`` the TCP speed per unit path speed, each joint i gets the
  limit ``tcp_cap |q_i'(s)| / v(s)``, which is equivalent to ``s_dot <= tcp_cap / v(s)``.

Rest-to-rest: zero path speed at both ends. TOPP-RA enforces the constraints at its grid
points only, so the trajectory resampled at the controller rate (``t = k / rate_hz``,
ending exactly on the last waypoint) is measured the way the verifier measures it
(finite differences of the samples, TCP speed by FK) and uniformly slowed down until
every measure is within its limit: the limits hold at every sample by construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.robots import RobotSpec
from cellrunner.planning.kinematics import ArmKinematics

DENSIFY_STEP_RAD = 0.03
#: Headroom kept below each limit after resampling (fraction).
RESAMPLE_HEADROOM = 0.995


@dataclass(frozen=True)
class MotionLimits:
    """Limits a plan may use, already multiplied by the margin (SI, rad)."""

    joint_speed_rad_s: np.ndarray
    joint_accel_rad_s2: np.ndarray
    tcp_speed_mps: float

    @classmethod
    def from_cell(
        cls,
        spec: RobotSpec,
        *,
        joint_speed_deg_s: float | tuple[float, ...] | None = None,
        joint_accel_deg_s2: float | tuple[float, ...] | None = None,
        tcp_speed_mps: float | None = None,
        margin: float = 0.95,
    ) -> MotionLimits:
        """Cell limits (degrees, as in the cell file) clamped to the controller's own, x
        ``margin``. Omitted values default to the controller's limits."""
        if not 0 < margin <= 1:
            raise ValueError(f"margin must be in (0, 1], not {margin}")
        speed = np.broadcast_to(
            np.asarray(joint_speed_deg_s if joint_speed_deg_s is not None else spec.joint_speed_max_deg_s, float), (6,)
        )
        accel = np.broadcast_to(
            np.asarray(joint_accel_deg_s2 if joint_accel_deg_s2 is not None else spec.joint_accel_max_deg_s2, float), (6,)
        )
        speed = np.minimum(speed, spec.joint_speed_max_deg_s)
        accel = np.minimum(accel, spec.joint_accel_max_deg_s2)
        tcp = min(tcp_speed_mps if tcp_speed_mps is not None else spec.tcp_speed_max_mps, spec.tcp_speed_max_mps)
        return cls(np.radians(speed) * margin, np.radians(accel) * margin, tcp * margin)

    def scaled(self, speed_fraction: float = 1.0, tcp_speed_mps: float | None = None) -> MotionLimits:
        """Slower limits for one move: joint speeds and accelerations x ``speed_fraction``,
        TCP speed capped at ``tcp_speed_mps`` (never above this one)."""
        f = float(min(max(speed_fraction, 1e-3), 1.0))
        tcp = self.tcp_speed_mps if tcp_speed_mps is None else min(tcp_speed_mps, self.tcp_speed_mps)
        return MotionLimits(self.joint_speed_rad_s * f, self.joint_accel_rad_s2 * f, tcp)


@dataclass(frozen=True)
class TimedPath:
    """Samples ``q_rad`` (N x 6) at ``t_s = k / rate_hz``, and ``s`` (N) the distance along
    the joint path (rad) of each sample, with ``s_waypoints`` that of each input waypoint."""

    rate_hz: float
    t_s: np.ndarray
    q_rad: np.ndarray
    s: np.ndarray
    s_waypoints: np.ndarray


def sample_measures(kin: ArmKinematics, q_rad: np.ndarray, rate_hz: float,
                    rest_before: bool = True, rest_after: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Finite-difference joint speeds (rad/s), accelerations (rad/s^2) and TCP speeds (m/s)
    of samples taken every 1/rate_hz s; ``rest_before``/``rest_after`` pad with the robot
    at rest on the first/last sample."""
    q = np.asarray(q_rad, float)
    if rest_before:
        q = np.vstack([q[:1], q])
    if rest_after:
        q = np.vstack([q, q[-1:]])
    dt = 1.0 / rate_hz
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    p = kin.p_world_tcp_many(q)
    tcp = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    return v, a, tcp


def time_path(
    kin: ArmKinematics,
    waypoints_rad: np.ndarray,
    limits: MotionLimits,
    rate_hz: float,
) -> TimedPath:
    """Time-optimal rest-to-rest trajectory through ``waypoints_rad`` (N x 6), sampled at
    ``rate_hz``; see the module docstring. Raises :class:`InfeasibleError` when TOPP-RA
    finds no parameterization."""
    import toppra as ta
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    wp = _dedupe(np.asarray(waypoints_rad, float))
    if len(wp) == 1:
        return TimedPath(rate_hz, np.zeros(1), wp.copy(), np.zeros(1), np.zeros(1))
    dense, s_dense, s_wp = _densify(wp)
    path = ta.SplineInterpolator(s_dense, dense, bc_type="natural")
    vlim = np.column_stack([-limits.joint_speed_rad_s, limits.joint_speed_rad_s])
    alim = np.column_stack([-limits.joint_accel_rad_s2, limits.joint_accel_rad_s2])
    tcp_cap = limits.tcp_speed_mps

    def tcp_vlim(s: float) -> np.ndarray:
        q = path(s)
        dq = path(s, 1)
        v = float(np.linalg.norm(kin.jacobian_tcp(q)[:3] @ dq))
        lim = np.full(6, 1e6) if v < 1e-9 else np.maximum(tcp_cap * np.abs(dq) / v, 1e-9)
        return np.column_stack([-lim, lim])

    constraints = [
        constraint.JointVelocityConstraint(vlim),
        constraint.JointAccelerationConstraint(alim),
        constraint.JointVelocityConstraintVarying(tcp_vlim),
    ]
    n_grid = int(min(max(60, 2 * len(wp)), 600))
    gridpoints = np.linspace(0.0, s_dense[-1], n_grid)
    try:
        instance = algo.TOPPRA(constraints, path, gridpoints=gridpoints, parametrizer="ParametrizeConstAccel")
        _, sd, _ = instance.compute_parameterization(0.0, 0.0)
    except Exception as exc:  # toppra raises its own exception types from its solvers
        raise InfeasibleError(f"time parameterization failed (TOPP-RA: {exc})") from exc
    if sd is None or not np.all(np.isfinite(sd)):
        raise InfeasibleError(
            "time parameterization failed (TOPP-RA found no speed profile within the joint "
            "speed, acceleration and TCP speed limits)"
        )
    s_of_t, duration = _s_of_time(np.asarray(sd, float), gridpoints)
    scale = 1.0
    for _ in range(8):
        n = max(1, int(math.ceil(duration * scale * rate_hz - 1e-9)))
        t = np.arange(n + 1) / rate_hz
        tau = np.minimum(t * duration / (n / rate_hz), duration)  # stretch onto the grid
        s = s_of_t(tau)
        q = path(s)
        q[0], q[-1] = wp[0], wp[-1]
        v, a, tcp = sample_measures(kin, q, rate_hz)
        ratio = max(
            float(np.max(np.abs(v) / limits.joint_speed_rad_s)),
            math.sqrt(float(np.max(np.abs(a) / limits.joint_accel_rad_s2))),
            float(np.max(tcp)) / tcp_cap,
        )
        if ratio <= RESAMPLE_HEADROOM:
            return TimedPath(rate_hz, t, q, s, s_wp)
        scale = (n / rate_hz) / duration * ratio / RESAMPLE_HEADROOM
    raise InfeasibleError(f"trajectory exceeds its limits after resampling (x{ratio:.3f})")


def _s_of_time(sd: np.ndarray, gridpoints: np.ndarray):
    """Path position as a function of time from TOPP-RA's path speeds ``sd`` on its grid,
    with constant path acceleration between grid points (its own parameterization), and
    the total duration (s)."""
    xs = sd**2
    ds = np.diff(gridpoints)
    dt = 2 * ds / np.maximum(sd[:-1] + sd[1:], 1e-12)
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    accel = (xs[1:] - xs[:-1]) / (2 * ds)

    def s_at(tau: np.ndarray) -> np.ndarray:
        tau = np.asarray(tau, float)
        i = np.clip(np.searchsorted(t_grid, tau, side="right") - 1, 0, len(ds) - 1)
        h = np.clip(tau - t_grid[i], 0.0, dt[i])
        return np.minimum(gridpoints[i] + sd[i] * h + 0.5 * accel[i] * h * h, gridpoints[i + 1])

    return s_at, float(t_grid[-1])


def _dedupe(wp: np.ndarray) -> np.ndarray:
    keep = [0] + [i for i in range(1, len(wp)) if np.abs(wp[i] - wp[i - 1]).max() > 1e-9]
    if len(keep) > 1 and np.abs(wp[-1] - wp[keep[-1]]).max() > 0:
        keep[-1] = len(wp) - 1
    return wp[keep]


def _densify(wp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points every <= DENSIFY_STEP_RAD (largest joint move) along the polyline, their
    cumulative joint-space distance, and that of the original waypoints."""
    points, s_points, s_wp = [wp[0]], [0.0], [0.0]
    s = 0.0
    for a, b in zip(wp[:-1], wp[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / DENSIFY_STEP_RAD)))
        length = float(np.linalg.norm(b - a))
        for k in range(1, n + 1):
            points.append(a + (b - a) * k / n)
            s_points.append(s + length * k / n)
        s += length
        s_wp.append(s)
    return np.array(points), np.array(s_points), np.array(s_wp)
