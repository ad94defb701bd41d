"""Time parameterization (TOPP-RA) of joint paths and resampling at the controller rate.

A path is a polyline of joint waypoints (rad). Its long edges are densified (no joint
moves more than ``DENSIFY_STEP_RAD`` between points), so that the spline keeps to them;
edges up to ``DENSIFY_MIN_EDGE_RAD`` stay whole (the chords of a rounded corner: a knot
inside each would make the spline straight between the arc's points and kinked at them,
7% slower on a wide arc), fitted with a cubic spline in the cumulative
joint-space distance ``s`` and time-optimally parameterized by TOPP-RA on a grid through
every densified point, then again on that grid refined where the speed changes (intervals
longer than ``REFINE_INTERVAL_S``: TOPP-RA's constant path acceleration per interval, held
to the limits at both ends, stretched starts, stops and curves by 2-5%), under

- joint speed limits x margin (rad/s),
- joint acceleration limits x margin (rad/s^2),
- each joint's torque (:mod:`.dynamics`: the arm's masses and inertias, its tool and
  heaviest part, a share of the joints' rated torques), as TOPP-RA's linear constraint
  ``-tau <= a(s) s_ddot + b(s) s_dot^2 <= tau``, where the limits carry an arm's dynamics
  (``MotionLimits.dynamics``): a UR10e's shoulder cannot brake a stretched arm at the
  controller's 40 rad/s^2, and a plan that asks it to overshoots,
- the TCP speed cap x margin (m/s), as a path-speed cap ``s_dot <= tcp_cap / v(s)`` with
  ``v(s) = |dp/ds|`` the TCP speed per unit path speed, computed for the whole grid at
  once by forward kinematics and given to TOPP-RA as per-joint limits
  ``cap(s) |q_i'(s)|``.

Rest-to-rest: zero path speed at both ends. TOPP-RA enforces the constraints at its grid
points only, so the trajectory resampled at the controller rate (``t = k / rate_hz``,
ending exactly on the last waypoint) is measured the way the verifier measures it
(finite differences of the samples, TCP speed by FK). Where a sample exceeds a limit,
the path speed is capped **locally**, on the grid points around that sample, at its speed
there divided by the excess, and TOPP-RA is solved again (at most ``LOCAL_ROUNDS``
times; the rest of the motion keeps its optimal speed). Only if that does not converge
is the whole motion slowed uniformly. The limits hold at every sample by construction.

toppra's algorithm module imports ``matplotlib.pyplot`` for its plotting helpers; it is
given a stand-in that imports the real pyplot on first use (:func:`_import_toppra`).
"""

from __future__ import annotations

import itertools
import math
import types
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import InfeasibleError, InternalError
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.robots import RobotSpec
from cellrunner.planning.kinematics import ArmKinematics

if TYPE_CHECKING:
    from cellrunner.planning.dynamics import ArmDynamics

#: path position (rad of joint travel) at the given times (s)
SOfTime = Callable[[np.ndarray], np.ndarray]

DENSIFY_STEP_RAD = 0.03
#: edges up to this long (largest joint move, rad) are not densified
DENSIFY_MIN_EDGE_RAD = 0.1
#: Where resampling exceeds a limit, the speed there is lowered this much more (fraction).
RESAMPLE_HEADROOM = 0.995
#: Rounds of local slow-down before the uniform fallback.
LOCAL_ROUNDS = 4
#: TOPP-RA's grid: every densified point, at least / at most this many points.
MIN_GRID_POINTS = 40
MAX_GRID_POINTS = 800
#: TOPP-RA plans against limits this much lower (its solver meets them to ~1e-9 only).
TOPPRA_TIGHTENING = 0.9995
#: After a first solve, grid intervals where the speed changes are split to take at most
#: this long (s), up to this many grid points in all (:meth:`_Problem.refine`) ...
REFINE_INTERVAL_S = 0.0075
MAX_REFINED_GRID_POINTS = 2000
#: ... an interval within this fraction of its speed bound at both ends is cruising
REFINE_CRUISE_TOLERANCE = 1e-3


@dataclass(frozen=True)
class MotionLimits:
    """Limits a plan may use, already multiplied by the margin (SI, rad)."""

    joint_speed_rad_s: np.ndarray
    joint_accel_rad_s2: np.ndarray
    tcp_speed_mps: float
    #: the arm's inverse dynamics and the joint torques a plan may ask (N m); None: the
    #: joint limits alone (an arm with no twin, or a caller that times kinematically)
    dynamics: ArmDynamics | None = None
    joint_torque_nm: np.ndarray | None = None

    @classmethod
    def from_cell(
        cls,
        spec: RobotSpec,
        *,
        joint_speed_deg_s: float | tuple[float, ...] | None = None,
        joint_accel_deg_s2: float | tuple[float, ...] | None = None,
        tcp_speed_mps: float | None = None,
        margin: float = 0.95,
        dynamics: ArmDynamics | None = None,
    ) -> MotionLimits:
        """Cell limits (degrees, as in the cell file) clamped to the controller's own, x
        ``margin``. Omitted values default to the controller's limits. ``dynamics``: the
        arm's, to keep each joint's torque under its share of the rated one too."""
        if not 0 < margin <= 1:
            raise InternalError(f"margin must be in (0, 1], not {margin}")
        speed = np.broadcast_to(
            np.asarray(
                joint_speed_deg_s if joint_speed_deg_s is not None else spec.joint_speed_max_deg_s,
                float,
            ),
            (6,),
        )
        accel = np.broadcast_to(
            np.asarray(
                joint_accel_deg_s2
                if joint_accel_deg_s2 is not None
                else spec.joint_accel_max_deg_s2,
                float,
            ),
            (6,),
        )
        speed = np.minimum(speed, spec.joint_speed_max_deg_s)
        accel = np.minimum(accel, spec.joint_accel_max_deg_s2)
        tcp = min(
            tcp_speed_mps if tcp_speed_mps is not None else spec.tcp_speed_max_mps,
            spec.tcp_speed_max_mps,
        )
        torque = None
        if dynamics is not None:
            from cellrunner.planning.dynamics import TORQUE_SHARE

            torque = dynamics.torque_max_nm * TORQUE_SHARE
        return cls(
            np.radians(speed) * margin, np.radians(accel) * margin, tcp * margin, dynamics, torque
        )

    def scaled(
        self,
        speed_fraction: float = 1.0,
        tcp_speed_mps: float | None = None,
        accel_fraction: float = 1.0,
    ) -> MotionLimits:
        """Slower limits for one move: joint speeds and accelerations x ``speed_fraction``,
        accelerations x ``accel_fraction`` too, TCP speed capped at ``tcp_speed_mps``
        (never above this one)."""
        f = float(min(max(speed_fraction, 1e-3), 1.0))
        g = float(min(max(accel_fraction, 1e-4), 1.0))
        tcp = (
            self.tcp_speed_mps if tcp_speed_mps is None else min(tcp_speed_mps, self.tcp_speed_mps)
        )
        torque = None if self.joint_torque_nm is None else self.joint_torque_nm * f * g
        return MotionLimits(
            self.joint_speed_rad_s * f, self.joint_accel_rad_s2 * f * g, tcp, self.dynamics, torque
        )


@dataclass(frozen=True)
class TimedPath:
    """Samples ``q_rad`` (N x 6) at ``t_s = k / rate_hz``, and ``s`` (N) the distance along
    the joint path (rad) of each sample, with ``s_waypoints`` that of each input waypoint."""

    rate_hz: float
    t_s: np.ndarray
    q_rad: np.ndarray
    s: np.ndarray
    s_waypoints: np.ndarray


def sample_measures(
    kin: ArmKinematics,
    q_rad: np.ndarray,
    rate_hz: float,
    rest_before: bool = True,
    rest_after: bool = True,
    p_world_tcp_m: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Finite-difference joint speeds (rad/s), accelerations (rad/s^2) and TCP speeds (m/s)
    of samples taken every 1/rate_hz s; ``rest_before``/``rest_after`` pad with the robot
    at rest on the first/last sample. ``p_world_tcp_m``: the samples' TCP positions
    (N x 3), when the caller has them already."""
    q = np.asarray(q_rad, float)
    p = kin.p_world_tcp_many(q) if p_world_tcp_m is None else np.asarray(p_world_tcp_m, float)
    if rest_before:
        q, p = np.vstack([q[:1], q]), np.vstack([p[:1], p])
    if rest_after:
        q, p = np.vstack([q, q[-1:]]), np.vstack([p, p[-1:]])
    dt = 1.0 / rate_hz
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
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
    wp = _dedupe(np.asarray(waypoints_rad, float))
    if len(wp) == 1:
        return TimedPath(rate_hz, np.zeros(1), wp.copy(), np.zeros(1), np.zeros(1))
    problem = _Problem(kin, wp, limits)
    sd = problem.solve(problem.tcp_cap)
    if problem.refine(sd):
        sd = problem.solve(problem.tcp_cap)
    cap = problem.tcp_cap.copy()
    for round_ in range(LOCAL_ROUNDS + 1):
        if round_:
            sd = problem.solve(cap)
        s_of_t, duration = _s_of_time(sd, problem.grid)
        t, s, q = _resample(problem, s_of_t, duration, 1.0, rate_hz)
        excess = _excess(kin, q, limits, rate_hz)
        if excess.max() <= 1.0:
            return TimedPath(rate_hz, t, q, s, problem.s_waypoints)
        cap = _capped_locally(problem.grid, sd, cap, s, excess)
    scale = 1.0
    for _ in range(8):  # uniform fallback
        scale *= float(excess.max()) / RESAMPLE_HEADROOM
        t, s, q = _resample(problem, s_of_t, duration, scale, rate_hz)
        excess = _excess(kin, q, limits, rate_hz)
        if excess.max() <= 1.0:
            return TimedPath(rate_hz, t, q, s, problem.s_waypoints)
    raise InfeasibleError(
        Failure(
            FailureKind.LIMITS,
            f"trajectory exceeds its limits after resampling (x{excess.max():.3f})",
        )
    )


def optimal_duration_s(
    kin: ArmKinematics, q_path_rad: np.ndarray, limits: MotionLimits, grid_points: int = 2000
) -> float:
    """The time-optimal rest-to-rest duration (s) of the path through the configurations
    ``q_path_rad`` (N x 6, e.g. a streamed trajectory), by TOPP-RA on a fine grid with no
    resampling: a lower bound for any trajectory on that path within ``limits``."""
    q = _dedupe(np.asarray(q_path_rad, float))
    if len(q) < 2:
        return 0.0
    step = np.abs(np.diff(q, axis=0)).max(axis=1)
    keep, travelled = [0], 0.0
    for k in range(1, len(q) - 1):  # points about 0.01 rad apart: the path, not the sampling
        travelled += step[k - 1]
        if travelled >= 0.01:
            keep.append(k)
            travelled = 0.0
    keep.append(len(q) - 1)
    problem = _Problem(kin, q[keep], limits, grid_points=grid_points, densify=False, tightening=1.0)
    return float(_s_of_time(problem.solve(problem.tcp_cap), problem.grid)[1])


class _Problem:
    """The spline path through the waypoints, its TOPP-RA grid and the TCP path-speed cap
    on that grid (rad/s of path speed)."""

    def __init__(
        self,
        kin: ArmKinematics,
        wp: np.ndarray,
        limits: MotionLimits,
        *,
        grid_points: int = 0,
        densify: bool = True,
        tightening: float = TOPPRA_TIGHTENING,
    ) -> None:
        ta = _import_toppra()
        self.wp, self.limits, self.tightening = wp, limits, tightening
        if densify:
            dense, s_dense, self.s_waypoints = _densify(wp)
        else:
            dense = wp
            s_dense = np.concatenate(
                [[0.0], np.cumsum(np.linalg.norm(np.diff(wp, axis=0), axis=1))]
            )
            self.s_waypoints = s_dense
        self.path = ta.SplineInterpolator(s_dense, dense, bc_type="natural")
        if grid_points:
            grid = np.linspace(0.0, s_dense[-1], grid_points)
        else:
            grid = np.union1d(s_dense, np.linspace(0.0, s_dense[-1], MIN_GRID_POINTS))
            if len(grid) > MAX_GRID_POINTS:
                grid = grid[np.round(np.linspace(0, len(grid) - 1, MAX_GRID_POINTS)).astype(int)]
        self.kin = kin
        self._set_grid(grid)

    def _set_grid(self, grid: np.ndarray) -> None:
        """The grid, the path's slope on it and the TCP path-speed cap there."""
        self.grid = grid
        self.dq_ds = np.abs(self.path(grid, 1))
        h, end = 1e-6, grid[-1]
        dp = self.kin.p_world_tcp_many(
            self.path(np.minimum(grid + h, end))
        ) - self.kin.p_world_tcp_many(self.path(np.maximum(grid - h, 0.0)))
        width = np.minimum(grid + h, end) - np.maximum(grid - h, 0.0)
        tcp_per_s = np.linalg.norm(dp, axis=1) / width
        self.tcp_cap = np.where(
            tcp_per_s < 1e-9,
            np.inf,
            self.limits.tcp_speed_mps * self.tightening / np.maximum(tcp_per_s, 1e-12),
        )

    def speed_bound(self, cap: np.ndarray) -> np.ndarray:
        """The largest path speed (s_dot) each grid point allows: joint speeds and ``cap``."""
        per_joint = (self.limits.joint_speed_rad_s * self.tightening)[None, :] / np.maximum(
            self.dq_ds, 1e-12
        )
        return np.asarray(np.minimum(per_joint.min(axis=1), cap))

    def refine(self, sd: np.ndarray) -> bool:
        """Split the grid intervals where the solution ``sd`` changes speed (not cruising
        at its speed bound) and that take longer than ``REFINE_INTERVAL_S``: TOPP-RA holds
        the path acceleration constant over an interval and meets the limits at both its
        ends, which costs time where the interval is long (starts, stops, curves). Whether
        the grid changed."""
        grid = self.grid
        dt = 2 * np.diff(grid) / np.maximum(sd[:-1] + sd[1:], 1e-12)
        bound = self.speed_bound(self.tcp_cap)
        at_bound = sd >= (1 - REFINE_CRUISE_TOLERANCE) * bound
        cruising = at_bound[:-1] & at_bound[1:]
        pieces = np.where(cruising, 1, np.ceil(dt / REFINE_INTERVAL_S)).astype(int)
        budget = MAX_REFINED_GRID_POINTS - len(grid)
        extra = int((pieces - 1).sum())
        if extra <= 0 or budget <= 0:
            return False
        if extra > budget:  # fewer splits everywhere rather than none somewhere
            pieces = 1 + np.floor((pieces - 1) * budget / extra).astype(int)
        fractions = [np.arange(1, k) / k for k in range(int(pieces.max()) + 1)]
        inner = [
            a + (b - a) * fractions[k]
            for a, b, k in zip(grid[:-1], grid[1:], pieces, strict=True)
            if k > 1
        ]
        self._set_grid(np.union1d(grid, np.concatenate(inner)))
        return True

    def solve(self, cap: np.ndarray) -> np.ndarray:
        """TOPP-RA's path speeds (s_dot) on the grid under the joint limits and ``cap``."""
        _import_toppra()
        from toppra import algorithm as algo
        from toppra import constraint

        alim = self.limits.joint_accel_rad_s2 * self.tightening
        # joint speed limits and the path-speed cap as one bound on s_dot^2 per grid point
        x_max = np.minimum(self.speed_bound(cap), 1e6) ** 2

        class PathSpeedBound(constraint.LinearConstraint):  # type: ignore[misc]  # toppra is untyped
            """s_dot^2 <= x_max on each grid point (computed above for the whole grid)."""

            def __init__(self) -> None:
                super().__init__()
                self.dof = len(alim)

            def compute_constraint_params(
                self, path: Any, gridpoints: np.ndarray
            ) -> tuple[np.ndarray | None, ...]:
                return (
                    None,
                    None,
                    None,
                    None,
                    None,
                    None,
                    np.column_stack([np.zeros(len(x_max)), x_max]),
                )

        constraints = [
            PathSpeedBound(),
            constraint.JointAccelerationConstraint(np.column_stack([-alim, alim])),
        ]
        dyn, tau = self.limits.dynamics, self.limits.joint_torque_nm
        if dyn is not None and tau is not None:
            constraints.append(_torque_bound(constraint, dyn, tau * self.tightening))
        try:
            instance = algo.TOPPRA(
                constraints, self.path, gridpoints=self.grid, parametrizer="ParametrizeConstAccel"
            )
            _, sd, _ = instance.compute_parameterization(0.0, 0.0)
        except Exception as exc:  # toppra raises its own exception types from its solvers
            raise InfeasibleError(
                Failure(FailureKind.LIMITS, f"time parameterization failed (TOPP-RA: {exc})")
            ) from exc
        if sd is None or not np.all(np.isfinite(sd)):
            raise InfeasibleError(
                Failure(
                    FailureKind.LIMITS,
                    "time parameterization failed (TOPP-RA found no speed profile within the "
                    "joint speed, acceleration and TCP speed limits)",
                )
            )
        return np.asarray(sd, float)


def _torque_bound(constraint: Any, dyn: ArmDynamics, tau_nm: np.ndarray) -> Any:
    """TOPP-RA's constraint ``-tau <= a(s) s_ddot + b(s) s_dot^2 <= tau`` on each grid
    point (:mod:`.dynamics`), collocated as the joint acceleration constraint is."""

    class TorqueBound(constraint.LinearConstraint):  # type: ignore[misc]  # toppra is untyped
        def __init__(self) -> None:
            super().__init__()
            self.dof = len(tau_nm)
            self.identical = True

        def compute_constraint_params(
            self, path: Any, gridpoints: np.ndarray
        ) -> tuple[np.ndarray | None, ...]:
            a, b = dyn.path_terms(path(gridpoints), path(gridpoints, 1), path(gridpoints, 2))
            eye = np.eye(self.dof)
            F = np.vstack([eye, -eye])
            g = np.concatenate([tau_nm, tau_nm])
            return a, b, np.zeros_like(a), F, g, None, None

    return TorqueBound()


def _resample(
    problem: _Problem, s_of_t: SOfTime, duration: float, scale: float, rate_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples at ``t = k / rate_hz`` of the profile stretched by ``scale``, ending
    exactly on the last waypoint: (t, s, q). The cubic spline overshoots a little where
    the polyline it interpolates bends (up to ~2e-5 rad measured, at the end of a blend
    arc): a joint that runs along the edge of its range there (a wrist at -180 deg along
    a descend) would leave the range, so samples are kept within it."""
    n = max(1, math.ceil(duration * scale * rate_hz - 1e-9))
    t = np.arange(n + 1) / rate_hz
    tau = np.minimum(t * duration / (n / rate_hz), duration)
    s = s_of_t(tau)
    q = np.clip(problem.path(s), problem.kin.q_min_rad, problem.kin.q_max_rad)
    q[0], q[-1] = problem.wp[0], problem.wp[-1]
    return t, s, q


def _excess(kin: ArmKinematics, q: np.ndarray, limits: MotionLimits, rate_hz: float) -> np.ndarray:
    """Per sample, how far over its limits the trajectory is there (1 = at a limit), as a
    path-speed factor: speed and TCP ratios, square root of the acceleration ratio."""
    v, a, tcp = sample_measures(kin, q, rate_hz)
    rv = np.max(np.abs(v) / limits.joint_speed_rad_s, axis=1)  # N + 1 differences
    rt = tcp / limits.tcp_speed_mps
    ra = np.sqrt(np.max(np.abs(a) / limits.joint_accel_rad_s2, axis=1))  # N second differences
    if limits.dynamics is not None and limits.joint_torque_nm is not None:
        # second difference k is centred on sample k (the first one padded with rest),
        # its speed the mean of the differences either side of it
        tau = limits.dynamics.torques_nm(q, (v[:-1] + v[1:]) / 2, a)
        ra = np.maximum(ra, np.sqrt(np.max(np.abs(tau) / limits.joint_torque_nm, axis=1)))
    per_sample = np.zeros(len(q))
    # difference k lies between samples k-1 and k (padded with rest at both ends)
    for ratio, offset in ((np.maximum(rv, rt), 1), (ra, 1)):
        lo = np.clip(np.arange(len(ratio)) - offset, 0, len(q) - 1)
        hi = np.clip(np.arange(len(ratio)) - offset + 1, 0, len(q) - 1)
        np.maximum.at(per_sample, lo, ratio)
        np.maximum.at(per_sample, hi, ratio)
    return per_sample


def _capped_locally(
    grid: np.ndarray, sd: np.ndarray, cap: np.ndarray, s: np.ndarray, excess: np.ndarray
) -> np.ndarray:
    """``cap`` lowered on the grid points around each sample over its limits to the speed
    there divided by the excess (and the headroom)."""
    cap = cap.copy()
    for k in (int(i) for i in np.nonzero(excess > 1.0)[0]):
        lo = max(int(np.searchsorted(grid, s[max(k - 2, 0)])) - 2, 0)
        hi = min(int(np.searchsorted(grid, s[min(k + 2, len(s) - 1)])) + 2, len(grid))
        target = np.maximum(sd[lo:hi], 1e-3) * RESAMPLE_HEADROOM / excess[k]
        cap[lo:hi] = np.minimum(cap[lo:hi], target)
    return cap


def _import_toppra() -> Any:  # the toppra module (untyped)
    """toppra, imported without loading ``matplotlib.pyplot`` (0.45 s), which its
    algorithm module imports at the top for plotting helpers we never call: while toppra
    loads, ``matplotlib.pyplot`` is a stand-in that imports the real module on first use."""
    import sys

    if "toppra" in sys.modules or "matplotlib.pyplot" in sys.modules:
        import toppra

        return toppra

    class _LazyPyplot(types.ModuleType):
        def __getattr__(self, name: str) -> Any:
            import importlib

            sys.modules.pop("matplotlib.pyplot", None)
            real = importlib.import_module("matplotlib.pyplot")
            return getattr(real, name)

    stand_in = _LazyPyplot("matplotlib.pyplot")
    added: dict[str, types.ModuleType] = {"matplotlib.pyplot": stand_in}
    if "matplotlib" not in sys.modules:
        parent = types.ModuleType("matplotlib")
        parent.pyplot = stand_in  # type: ignore[attr-defined]  # a stand-in module's attribute
        added["matplotlib"] = parent
    sys.modules.update(added)
    try:
        import toppra
    finally:
        for name, module in added.items():
            if sys.modules.get(name) is module:
                del sys.modules[name]
    return toppra


def _s_of_time(sd: np.ndarray, gridpoints: np.ndarray) -> tuple[SOfTime, float]:
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
        return np.asarray(
            np.minimum(gridpoints[i] + sd[i] * h + 0.5 * accel[i] * h * h, gridpoints[i + 1])
        )

    return s_at, float(t_grid[-1])


def _dedupe(wp: np.ndarray) -> np.ndarray:
    keep = [0] + [i for i in range(1, len(wp)) if np.abs(wp[i] - wp[i - 1]).max() > 1e-9]
    if len(keep) > 1 and np.abs(wp[-1] - wp[keep[-1]]).max() > 0:
        keep[-1] = len(wp) - 1
    return wp[keep]


def _densify(wp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points every <= DENSIFY_STEP_RAD (largest joint move) along the polyline's edges
    longer than DENSIFY_MIN_EDGE_RAD, their cumulative joint-space distance, and that of
    the original waypoints."""
    points, s_points, s_wp = [wp[0]], [0.0], [0.0]
    s = 0.0
    for a, b in itertools.pairwise(wp):
        span = np.abs(b - a).max()
        n = 1 if span <= DENSIFY_MIN_EDGE_RAD else max(1, math.ceil(span / DENSIFY_STEP_RAD))
        length = float(np.linalg.norm(b - a))
        for k in range(1, n + 1):
            points.append(a + (b - a) * k / n)
            s_points.append(s + length * k / n)
        s += length
        s_wp.append(s)
    return np.array(points), np.array(s_points), np.array(s_wp)
