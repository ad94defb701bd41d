"""Many periods of a streamed motion in one call, where the backend can look ahead (the
MuJoCo twin: :mod:`cellrunner.sim.lookahead`).

While a motion streams its approved set-points and nothing else happens, every period
does the same: the engine reads the state, samples the tracking error every
``TRACK_EVERY`` ticks, checks the step's timeout and (carrying a part) the gripper's
sensor and the carried load, and sends the next set-point. :func:`fast_forward` asks
the backend for the coming periods' measurements first, runs those same checks over
them, and lets the backend take over only the periods before the first one where any
check (the engine's or the twin's own: contacts, inputs) would fire, or an observer
wants to act. That first period then runs through the ordinary per-period path, so a
fault is met at the same period, with the same state, as without look-ahead.

A step that holds the arm still while it waits (the jaws closing or opening, a weighing,
a wait; see :class:`~cellrunner.execution.context.Hold`) is looked ahead the same way:
its set-point stays, and the periods pass up to the first one where the step's own
condition (its time, its timeout), the step's timeout, an observer or the twin (a
contact, an input changing) would act; the wrench samples it takes on the way are taken
from the recorded periods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, TypeGuard, runtime_checkable

import numpy as np

from cellrunner.execution.context import Hold, JobContext
from cellrunner.execution.steps import (
    LOAD_LOST_FRACTION,
    carried_loads_N,
    next_load_lp,
    watches_load,
)
from cellrunner.model.robot_state import Safety
from cellrunner.model.trajectory import ApprovedTrajectory

#: a look-ahead shorter than this is not worth its fixed cost (periods)
MIN_PERIODS = 8
#: tracking errors from batched kinematics within this of the largest are recomputed
#: with the per-period kinematics, so the maximum kept is the per-period one to the last
#: bit (m; the two differ by ~1e-16 m)
TRACK_TOLERANCE_M = 1e-9
#: this many tracking samples or fewer are computed one by one (a batched kinematics
#: call costs about as much as ten samples taken one by one)
TRACK_ONE_BY_ONE = 8


class Preview(Protocol):
    """The coming periods as a backend would measure them (rows: periods): the first
    ``quiet`` need nothing of the backend itself."""

    quiet: int
    time_s: np.ndarray
    q_rad: np.ndarray
    wrench_N: np.ndarray


@runtime_checkable
class LooksAhead(Protocol):
    """A backend that can preview a streamed motion's coming periods and take them over
    (the sim backend; see :class:`~cellrunner.backends.sim.backend.SimBackend`)."""

    def look_ahead(self, trajectory: ApprovedTrajectory, next_index: int, periods: int) -> Any: ...

    def commit_look_ahead(self, preview: Any, periods: int) -> None: ...

    def discard_look_ahead(self, preview: Any) -> None: ...

    def servo(self, trajectory: ApprovedTrajectory, index: int) -> None: ...

    def look_ahead_hold(self, periods: int) -> Any: ...

    @property
    def rate_hz(self) -> float: ...


@dataclass(frozen=True)
class Clock:
    """What bounds a look-ahead in time: the runner's tick count (tracking samples every
    ``track_every`` ticks), the step's start and timeout, and ``until_s``, the first
    time (s) at which someone (an observer, the job's time limit) wants a period of its
    own."""

    ticks: int
    track_every: int
    step_started_s: float
    step_timeout_s: float
    until_s: float


def fast_forward(ctx: JobContext, clock: Clock, max_periods: int) -> int:
    """Advance a streaming motion by up to ``max_periods`` periods in one call; return
    how many periods passed (0: none, step the next period as usual)."""
    stream, state, backend = ctx.stream, ctx.state, ctx.backend
    if state is None or state.safety is not Safety.NORMAL or not _looks_ahead(backend):
        return 0
    if stream is None:
        return 0 if ctx.hold is None else _hold(ctx, ctx.hold, backend, clock, max_periods)
    carry = ctx.carry
    if carry is not None and (
        "sensor_false_since" in ctx.notes
        or (carry.confirm is not None and not state.inputs.get(carry.confirm))
    ):
        return 0
    q_plan = stream.approved.trajectory.q_rad
    n = min(max_periods, len(q_plan) - stream.next_index)
    if n < MIN_PERIODS:
        return 0
    preview: Preview | None = backend.look_ahead(stream.approved, stream.next_index, n)
    if preview is None:
        return 0
    t = preview.time_s
    m = min(
        preview.quiet,
        _first(t - clock.step_started_s > clock.step_timeout_s),
        _first(t >= clock.until_s),
    )
    load_lp = None
    if watches_load(carry) and m:
        assert carry is not None and carry.load_N is not None  # watches_load says so
        accel = stream.tcp_accel_mps2
        rows = None if accel is None else accel[stream.next_index - 1 :]
        m, load_lp = _carried_load(
            preview.wrench_N, m, carry, ctx.notes.get("load_lp"), rows, stream.gravity_mps2
        )
    if m < 1:
        backend.discard_look_ahead(preview)
        return 0
    j0 = stream.next_index - 1  # the set-point commanded now: period 1 runs on it
    _track(ctx, clock, q_plan[j0 : j0 + m], preview.q_rad[:m])
    backend.commit_look_ahead(preview, m)
    ctx.read()  # period m's tick reads the state ...
    if carry is not None:
        ctx.notes.pop("sensor_false_since", None)
        if load_lp is not None:
            ctx.notes["load_lp"] = load_lp
    i = j0 + m  # ... and sends the next set-point
    backend.servo(stream.approved, i)
    ctx.commanded_q = q_plan[i]
    stream.next_index = i + 1
    return m


def _looks_ahead(backend: object) -> TypeGuard[LooksAhead]:
    """Whether ``backend`` looks ahead, judged once per class (a protocol check costs
    ~20 us, and this runs every period)."""
    kind = type(backend)
    known = _LOOKS_AHEAD.get(kind)
    if known is None:
        known = _LOOKS_AHEAD[kind] = isinstance(backend, LooksAhead)
    return known


_LOOKS_AHEAD: dict[type, bool] = {}


def _hold(ctx: JobContext, hold: Hold, backend: LooksAhead, clock: Clock, max_periods: int) -> int:
    """Up to ``max_periods`` periods of a step waiting with the arm still (``hold``)."""
    # its end in time is known: roll out only the periods before it (the physics past a
    # cut would be computed in vain, and a cut preview is rolled out again to commit)
    periods0 = round(ctx.now_s * backend.rate_hz)
    max_periods = _hold_periods(
        hold, clock, (periods0 + np.arange(1, max_periods + 1)) / backend.rate_hz
    )
    if max_periods < MIN_PERIODS:
        return 0
    preview: Preview | None = backend.look_ahead_hold(max_periods)
    if preview is None:
        return 0
    waited = preview.time_s - hold.t0_s  # as the step computes it, period by period
    m = min(preview.quiet, _hold_periods(hold, clock, preview.time_s))
    if m < 1:
        backend.discard_look_ahead(preview)
        return 0
    if ctx.commanded_q is not None:
        _track(ctx, clock, np.broadcast_to(ctx.commanded_q, (m, 6)), preview.q_rad[:m])
    if hold.samples is not None:
        for r in np.flatnonzero(waited[:m] >= hold.sample_from_s).tolist():
            hold.samples.append(np.array(preview.wrench_N[r, :3]))
    backend.commit_look_ahead(preview, m)
    ctx.read()  # period m's tick reads the state; the step waits on
    return m


def _hold_periods(hold: Hold, clock: Clock, t: np.ndarray) -> int:
    """How many of the periods ending at times ``t`` (s) pass before the step, its
    timeout or an observer acts, as far as time decides it."""
    waited = t - hold.t0_s
    return min(
        _first(t - clock.step_started_s > clock.step_timeout_s),
        _first(t >= clock.until_s),
        _first(waited >= hold.timeout_s),
        _first(~(waited < hold.until_s)),
    )


def _first(fires: np.ndarray) -> int:
    """Index of the first true element (the count of leading false ones)."""
    hits = np.flatnonzero(fires)
    return int(hits[0]) if len(hits) else len(fires)


def _carried_load(
    wrench_N: np.ndarray,
    m: int,
    carry: Any,
    load_lp: float | None,
    accel_mps2: np.ndarray | None = None,
    gravity_mps2: np.ndarray | None = None,
) -> tuple[int, float | None]:
    """Run the carried-load low-pass over periods ``0..m-1`` as the per-period check
    does (``accel_mps2``: the planned TCP acceleration of the set-point each period runs
    on); return the periods before it would report the part lost, and its value after
    them."""
    lp = carry.load_N if load_lp is None else load_lp
    floor = LOAD_LOST_FRACTION * carry.min_N
    kept: float | None = None
    force = wrench_N[:m].T[:3]
    accel = None if accel_mps2 is None else accel_mps2[:m].T
    gravity = None if gravity_mps2 is None else gravity_mps2.tolist()
    loads = carried_loads_N(force, carry, accel, gravity, np.sqrt, np.maximum).tolist()
    for k, load in enumerate(loads):
        lp = next_load_lp(lp, load)
        if lp < floor:
            return k, kept
        kept = lp
    return m, kept


def _track(ctx: JobContext, clock: Clock, q_cmd: np.ndarray, q_meas: np.ndarray) -> None:
    """The tracking-error samples the per-period ticks would take in these periods; the
    largest is recomputed with the per-period kinematics, so it is theirs exactly."""
    every = clock.track_every
    first = -(clock.ticks + 1) % every  # row k samples when (ticks + k + 1) % every == 0
    cmd, meas = q_cmd[first::every], q_meas[first::every]
    motions = ctx.motions
    arms = getattr(motions, "tcp_lever_arms_m", None)
    if arms is not None and len(cmd):  # drop the rows that cannot beat the largest so far
        keep = np.abs(cmd - meas) @ arms() + TRACK_TOLERANCE_M > ctx.tracking_error_m
        cmd, meas = cmd[keep], meas[keep]
    many = getattr(motions, "tcp_positions_m", None)
    if many is not None and len(cmd) > TRACK_ONE_BY_ONE:
        p = many(np.concatenate([cmd, meas]))
        err = np.linalg.norm(p[: len(cmd)] - p[len(cmd) :], axis=1)
        top = float(err.max())
        if top + TRACK_TOLERANCE_M <= ctx.tracking_error_m:
            return
        near = err >= top - 2 * TRACK_TOLERANCE_M
        cmd, meas = cmd[near], meas[near]
    for q_c, q_m in zip(cmd, meas, strict=True):
        p_cmd = motions.tcp_position_m(q_c)
        p_meas = motions.tcp_position_m(q_m)
        error = math.dist(p_cmd.tolist(), p_meas.tolist())
        if error > ctx.tracking_error_m:
            ctx.tracking_error_m = error
