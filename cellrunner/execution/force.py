"""The force steps on every backend: a guarded servo along the approved straight line.

``move_until_contact`` and ``insert`` stream the line ``check`` approved (to
``max_distance`` / ``depth``) set-point by set-point, as every motion does, and watch the
wrist force (the controller's ``actual_TCP_force``, base axes) against a baseline taken
standing still just before. A force rise above the step's limit over the last three
measurements (or three times the limit at once) stops the arm (stopJ / servoStop) where
it is:

- ``move_until_contact``: contact is success, and the arm goes back along the line to
  where the contact began (as ur_rtde's moveUntilContact retracts); the line's end without
  contact fails the step (3 when a part is carried, which was being set down; else 1,
  nothing found);
- ``insert``: the depth reached past the frame (the TCP measured along the frame's Z)
  must lie in ``expect_depth``; outside it the place failed (3), with the depth in the
  message. A press fit (``force: {min}``) whose force never built up to ``min`` on the way
  in failed too (3): the part went in loose (a worn hole, the wrong part).

Why not ur_rtde's moveUntilContact: it is a speedL without an end, so it could run past
the line ``check`` approved; the guarded servo cannot (and reads the same sensor).
Each period's force is kept in ``ctx.notes['force_trace']`` as (t_s, step index, N) for
the report's wrist-force plot.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np

from cellrunner.execution.context import JobContext
from cellrunner.execution.outcome import OK, Outcome
from cellrunner.execution.steps import (
    AVERAGE_S,
    SETTLE_S,
    START_TOLERANCE_RAD,
    sensor_dropped,
)
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step
from cellrunner.model.step import StepKind
from cellrunner.model.trajectory import ApprovedTrajectory, backwards

#: one sample of a force step's trace: (time s, step index, wrist force above baseline N)
ForceSample = tuple[float, int, float]

#: after a contact stop, wait at most this long for the arm to stand still (s)
STOP_WAIT_S = 1.0
#: joint speed under which the arm stands still (rad/s)
STILL_RAD_S = 2e-3
#: the line stops when the mean of the last CONFIRM_SAMPLES measurements is over the
#: limit, or at once on one over HARD_HIT_FACTOR x the limit: a jolt of a few periods (a
#: late set-point shakes the tool's mass) is not a contact, a hard hit is
CONFIRM_SAMPLES = 3
HARD_HIT_FACTOR = 3.0
#: contact begins where the force last rose above this fraction of the step's limit and
#: stayed above it until the stop: the tool's mass shakes the wrist as the arm sets off
#: (1.6-2.2 N with the peg tool at 10 mm/s on the twin), which is no contact
TOUCH_FRACTION = 0.2
#: a measurement more than LATE_PERIODS periods after the one before says the set-points
#: stalled (this side was late): the arm stopped short and lurched on, and the tool's mass
#: shakes the wrist sensor for a few milliseconds (7-11 N with a UR3e's peg tool at
#: 10 mm/s, measured on the twin, gone 8-10 ms after). The measurements of the JOLT_S
#: from it do not count towards the confirmation (a hard hit still stops at once): 6 at
#: 500 Hz, 2 at 125 Hz
LATE_PERIODS = 1.5
JOLT_S = 0.012


def run_force(ctx: JobContext, step: Step, resume: bool = False) -> Generator[None, None, Outcome]:
    """Stream ``step``'s approved line until its force limit; the step's Outcome."""
    baseline = yield from _baseline(ctx)
    args = step.args
    limit_N = args.force if step.kind == StepKind.MOVE_UNTIL_CONTACT else args.force.max
    approved = _approved_line(ctx, step, resume)
    trace = ctx.notes.setdefault("force_trace", [])
    first = len(trace)
    streamed = yield from _stream_until_contact(ctx, step, approved, baseline, limit_N, trace)
    if isinstance(streamed, Outcome):
        return streamed
    if streamed.force_N is not None:
        ctx.backend.stop_motion()
        ctx.commanded_q = None  # pressing, not tracking
        yield from _until_still(ctx, trace, step, baseline)
    if step.kind == StepKind.MOVE_UNTIL_CONTACT:
        if (
            streamed.force_N is not None
        ):  # back to where the contact began, as moveUntilContact does
            i_touch = streamed.i if streamed.touch_i is None else streamed.touch_i
            yield from _retract(
                ctx, approved, streamed.i, max(i_touch - 1, 0), trace, step, baseline
            )
            return OK
        code = ResultCode.PLACE_FAILED if ctx.carry is not None else ResultCode.NO_PART
        return Outcome.failed(
            code,
            f"no contact within {args.max_distance * 1000:.1f} mm "
            f"(force stayed under {limit_N:g} N)",
        )
    peak_N = max((sample[2] for sample in trace[first:]), default=0.0)
    return _insertion_outcome(ctx, step, streamed.force_N, peak_N)


def _approved_line(ctx: JobContext, step: Step, resume: bool) -> ApprovedTrajectory:
    """The step's nominal approved motion, or one replanned from the measured joints when
    resuming or when the arm is more than START_TOLERANCE_RAD from its start."""
    q_now = ctx.last_state.q_rad
    approved = None if resume else ctx.motions.nominal(step)
    if (
        approved is None
        or np.max(np.abs(approved.trajectory.q_rad[0] - q_now)) > START_TOLERANCE_RAD
    ):
        approved = ctx.motions.replan(step, q_now, carrying=ctx.carry is not None)
    return approved


@dataclass(frozen=True)
class _Streamed:
    """How the line's streaming ended: the contact force (N, None when the line ran out),
    the last set-point index sent, and where the force first rose (None if it fell back)."""

    force_N: float | None
    i: int
    touch_i: int | None


def _stream_until_contact(
    ctx: JobContext,
    step: Step,
    approved: ApprovedTrajectory,
    baseline: list[float],
    limit_N: float,
    trace: list[ForceSample],
) -> Generator[None, None, _Streamed | Outcome]:
    """Send the line's set-points one per tick until the force (N, off ``baseline``, in the
    sensor's frame) confirms a contact over ``limit_N`` or hits hard; a failed Outcome if
    a sensed part drops."""
    q = approved.trajectory.q_rad
    late_s = LATE_PERIODS / approved.trajectory.rate_hz
    # from the baseline's last measurement: a stall right at the start is a stall too
    touch_i, t_last, i = None, ctx.now_s, 0
    recent: list[float] = []
    shaken_until = -math.inf  # the end of a jolt (s)
    for i in range(len(q)):
        ctx.backend.servo(approved, i)
        ctx.commanded_q = q[i]
        yield
        if ctx.now_s == t_last:
            continue  # no new measurement this period (a late controller package)
        if ctx.now_s - t_last > late_s:
            shaken_until, recent = ctx.now_s + JOLT_S, []
        t_last = ctx.now_s
        force_N = math.dist(np.asarray(ctx.last_state.wrench_N[:3]).tolist(), baseline)
        trace.append((ctx.now_s, step.index, force_N))
        sensor = sensor_dropped(ctx)  # (the wrist load is the contact's business here)
        if sensor is not None:
            ctx.backend.stop_motion()
            return Outcome.failed(
                ResultCode.PART_LOST, f"part lost during {step.kind}: the {sensor} dropped"
            )
        if force_N > HARD_HIT_FACTOR * limit_N:
            return _Streamed(force_N, i, touch_i)
        if ctx.now_s < shaken_until:
            continue
        if force_N <= TOUCH_FRACTION * limit_N:
            touch_i = None  # a rise that fell back (the tool's mass as the arm sets off)
        elif touch_i is None:
            touch_i = i
        recent = (recent + [force_N])[-CONFIRM_SAMPLES:]
        if sum(recent) / CONFIRM_SAMPLES > limit_N:
            return _Streamed(force_N, i, touch_i)
    return _Streamed(None, i, touch_i)


def _insertion_outcome(
    ctx: JobContext, step: Step, contact_N: float | None, peak_N: float
) -> Outcome:
    """An insertion's Outcome: OK when the depth reached (m) is within the step's window
    and, for a press fit, the force (``peak_N``, the most above the baseline) built up to
    its ``force.min``."""
    depth_m = _depth_m(ctx, step)
    lo, hi = step.args.depth_window_m
    how = f"stopped at {contact_N:.1f} N" if contact_N is not None else "no force stop"
    if not lo - 1e-4 <= depth_m <= hi + 1e-4:
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"inserted {depth_m * 1000:.1f} mm, expected "
            f"{lo * 1000:.1f}-{hi * 1000:.1f} mm ({how})",
        )
    low_N = step.args.force.min
    if low_N is not None and peak_N < low_N:
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"press fit not made: the force built up to {peak_N:.1f} N, under the "
            f"{low_N:g} N of force.min, by {depth_m * 1000:.1f} mm (the part went in loose)",
        )
    if low_N is not None:
        return Outcome(True, message=f"press fit made: {peak_N:.1f} N by {depth_m * 1000:.1f} mm")
    return OK


def _retract(
    ctx: JobContext,
    approved: ApprovedTrajectory,
    i_from: int,
    i_to: int,
    trace: list[ForceSample],
    step: Step,
    baseline: list[float],
) -> Generator[None, None, None]:
    """Stream the approved line backwards from set-point ``i_from`` to ``i_to``, then stand."""
    back = backwards(approved, i_from, i_to)
    for k in range(len(back.trajectory.q_rad)):
        ctx.backend.servo(back, k)
        ctx.commanded_q = back.trajectory.q_rad[k]
        yield
        trace.append(
            (
                ctx.now_s,
                step.index,
                math.dist(np.asarray(ctx.last_state.wrench_N[:3]).tolist(), baseline),
            )
        )
    yield from _until_still(ctx, trace, step, baseline)


def _baseline(ctx: JobContext) -> Generator[None, None, list[float]]:
    samples = []
    t0 = ctx.now_s
    while ctx.now_s - t0 < SETTLE_S + AVERAGE_S:
        if ctx.now_s - t0 >= SETTLE_S:
            samples.append(np.asarray(ctx.last_state.wrench_N[:3], float))
        yield
    if not samples:
        samples.append(np.asarray(ctx.last_state.wrench_N[:3], float))
    mean: list[float] = np.mean(samples, axis=0).tolist()
    return mean


def _until_still(
    ctx: JobContext, trace: list[ForceSample], step: Step, baseline: list[float]
) -> Generator[None, None, None]:
    t0 = ctx.now_s
    while ctx.now_s - t0 < STOP_WAIT_S:
        yield
        trace.append(
            (
                ctx.now_s,
                step.index,
                math.dist(np.asarray(ctx.last_state.wrench_N[:3]).tolist(), baseline),
            )
        )
        if ctx.now_s - t0 > 0.05 and np.max(np.abs(ctx.last_state.qd_rad_s)) < STILL_RAD_S:
            return


def _depth_m(ctx: JobContext, step: Step) -> float:
    """How far past the insert's frame the TCP stands, along the frame's Z (m)."""
    T_end = step.T_world_tcp
    assert T_end is not None  # an insert goes to a frame
    z = T_end[:3, 2]
    p_frame = T_end[:3, 3] - step.args.depth * z
    p_tcp = ctx.motions.tcp_position_m(ctx.last_state.q_rad, step)
    return float(np.dot(np.asarray(p_tcp) - p_frame, z))
