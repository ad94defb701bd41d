"""Step behaviours, each a generator that issues at most one command per controller tick
and yields; ``return`` hands back the :class:`Outcome`. The job runner advances exactly
one of them per tick, so nothing here blocks.

Sensing, never flags: a grip is confirmed by its input and the wrist load; a dropped part
is noticed by the jaw sensor and the load falling away.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from cellrunner.backends.base import RobotState
from cellrunner.execution.context import Carry, Hold, JobContext, Stream
from cellrunner.execution.correction import corrected
from cellrunner.execution.outcome import OK, Outcome, StepGen
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step
from cellrunner.model.trajectory import ApprovedTrajectory

#: joint distance (rad, max over joints) under which the arm is "at" a trajectory's start
START_TOLERANCE_RAD = 2e-3
#: a planned continuation slower than this (rad/s) may start from rest as it is
CONTINUATION_MIN_RAD_S = 1e-3
#: the wrist load is averaged over this long when weighing or taking a baseline (s)
AVERAGE_S = 0.05
#: stand still this long before a wrist baseline or a weighing (motion transients, s)
SETTLE_S = 0.1
#: the jaw sensor must read false this long before the part counts as lost (debounce, s)
SENSOR_DEBOUNCE_S = 0.05
#: a motion that ends at rest ends when the arm stands this close to its last set-point
#: (rad, on every joint) ...
ARRIVE_RAD = math.radians(1.0)
#: ... or fails this long (s) after it
ARRIVE_TIMEOUT_S = 1.0
#: a trajectory whose last set-points move slower than this (rad/s) ends at rest (the
#: last period of a time-optimal stop still moves ~0.01 rad/s)
AT_REST_RAD_S = 0.05
#: a part set down is measured once it moves slower than this (m/s) ...
PLACE_REST_MPS = 0.01
#: ... or this long (s) after the step that let it go ended
PLACE_SETTLE_S = 1.0
#: a carried load that falls (low-passed) under this fraction of the grip's minimum: lost
LOAD_LOST_FRACTION = 0.5
#: the part's apparent weight is scaled by g / |g - a| (:func:`carried_load_N`), at most
#: by 1 / this
MIN_FELT_GRAVITY = 0.25


def run_motion(ctx: JobContext, step: Step, resume: bool = False) -> StepGen:
    """Stream the approved trajectory of ``step``; replan from where the arm is when it
    does not stand at the trajectory's start (after a stop or a retry). Force steps run
    through :func:`~cellrunner.execution.force.run_force` instead."""
    q_now = ctx.last_state.q_rad
    if "aligned_frame" in step.extra:  # an align before measured where this frame really is
        moved = corrected(ctx, step)
        if moved is not None:
            step, resume = moved, True
    approved = None if resume else ctx.motions.nominal(step)
    # the last set-point streamed is this trajectory's start: the arm is on its way there
    # (servo lag, more under load), so the approved trajectory continues; else it must stand there
    on_its_way = (
        approved is not None
        and ctx.commanded_q is not None
        and np.array_equal(approved.trajectory.q_rad[0], ctx.commanded_q)
    )
    if (
        approved is None
        or (
            not on_its_way
            and np.max(np.abs(approved.trajectory.q_rad[0] - q_now)) > START_TOLERANCE_RAD
        )
        or (
            ctx.motions.continues(step)
            and not (on_its_way and _streamed_into(ctx, approved))
            and _at_rest_for(approved, ctx.last_state)
        )
    ):
        approved = ctx.motions.replan(step, q_now, carrying=ctx.carry is not None)
    q = approved.trajectory.q_rad
    # a non-stop continuation starts on the set-point just streamed: don't send it twice
    first = (
        1
        if ctx.commanded_q is not None and len(q) > 1 and np.array_equal(q[0], ctx.commanded_q)
        else 0
    )
    if ctx.obstacles is not None:  # a watched cell: stop, wait, replan around the map
        from cellrunner.execution.obstacles import stream_watched

        failed = yield from stream_watched(ctx, step, approved, first, part_lost_outcome)
        if isinstance(failed, Outcome):
            return failed
        if failed is not None:  # the way stayed blocked: (108, why)
            return Outcome.failed(*failed)
        streamed = ctx.notes.pop("watched_path", approved)  # the last path it followed
        return (yield from _ended(ctx, step, streamed.trajectory.q_rad, streamed))
    # the index lives in ctx.stream so that a look-ahead (execution.lookahead) can move
    # the stream on by many periods at once
    stream = ctx.stream = Stream(approved, first, *_planned_accel(ctx, approved))
    while stream.next_index < len(q):
        i = stream.next_index
        ctx.backend.servo(approved, i)
        ctx.commanded_q = q[i]
        stream.next_index = i + 1
        yield
        lost = part_lost_outcome(ctx)
        if lost is not None:
            return lost
    ctx.stream = None
    return (yield from _ended(ctx, step, q, approved))


def part_lost_outcome(ctx: JobContext) -> Outcome | None:
    """While a part is carried: the failed outcome (2) once it is lost (the motion is
    stopped), else None."""
    if ctx.carry is None:
        return None
    lost = _part_lost(ctx)
    if not lost:
        return None
    ctx.stream = None
    ctx.backend.stop_motion()
    return Outcome.failed(ResultCode.PART_LOST, lost)


def _ended(ctx: JobContext, step: Step, q: np.ndarray, approved: ApprovedTrajectory) -> StepGen:
    """A motion streamed to its end (set-points ``q``): how fast it ended (a continuation
    may run on from it); ended at rest, the arm arriving there; and the place check."""
    rate_hz = approved.trajectory.rate_hz
    end_rad_s = float(np.abs(q[-1] - q[-2]).max()) * rate_hz if len(q) > 1 else 0.0
    ctx.notes["end_rad_s"] = end_rad_s
    if end_rad_s < AT_REST_RAD_S:
        short = yield from _arrive(ctx, step, approved, len(q) - 1)
        if not short.ok:
            return short
    return (yield from check_place(ctx, step))


def _arrive(ctx: JobContext, step: Step, approved: ApprovedTrajectory, last: int) -> StepGen:
    """Hold the last set-point until the arm stands within ``ARRIVE_RAD`` of it (a stream
    sent late, under load, leaves the servo behind its set-points when it ends: a job
    through ur_rtde once ended OK with the arm 5 deg short of home). Failed (105) when it
    has not arrived ``ARRIVE_TIMEOUT_S`` after the last set-point."""
    q_end = approved.trajectory.q_rad[last]
    t0 = ctx.now_s
    while True:
        gap = np.abs(np.asarray(ctx.last_state.q_rad) - q_end)
        if float(gap.max()) <= ARRIVE_RAD:
            return OK
        if ctx.now_s - t0 >= ARRIVE_TIMEOUT_S:
            j = int(np.argmax(gap))
            return Outcome.failed(
                ResultCode.STEP_TIMEOUT,
                f"the arm stopped {np.degrees(gap[j]):.1f} deg short of the end of step "
                f"{step.index} {step.kind} on joint {j + 1} ({ARRIVE_TIMEOUT_S:g} s after "
                "its last set-point)",
            )
        ctx.backend.servo(approved, last)
        ctx.commanded_q = q_end
        yield


def check_place(ctx: JobContext, step: Step) -> StepGen:
    """Where the backend can see the parts (the twin), the part just set down must rest
    within the cell's place tolerance of where the task put it, carried by a fixture or
    another part (SPEC section 11). It is measured once it came to rest (waiting up to
    ``PLACE_SETTLE_S``): a part still falling is judged where it landed."""
    target = step.extra.get("place_check")
    inspect = getattr(ctx.backend, "inspect_place", None)
    if target is None or inspect is None:
        return OK
    t0 = ctx.now_s
    found = inspect(target["T_world_tcp"])
    while (
        found is not None
        and (found.speed_mps > PLACE_REST_MPS or found.resting_on is None)
        and ctx.now_s - t0 < PLACE_SETTLE_S
    ):
        yield
        found = inspect(target["T_world_tcp"])
    if found is None:
        return OK
    tol_m, tol_deg = target["tolerance"]
    if found.judged_m > tol_m or found.angle_deg > tol_deg or found.resting_on is None:
        where = "" if found.resting_on is not None else "; nothing carries it"
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"place failed: part {found.part!r} is {found.offset_m * 1000:.1f} mm "
            f"and {found.angle_deg:.1f} deg from its target (tolerance {tol_m * 1000:g} mm, "
            f"{tol_deg:g} deg){where}",
        )
    return OK


def _streamed_into(ctx: JobContext, approved: ApprovedTrajectory) -> bool:
    """The set-points just streamed ran into this continuation at its speed (the motion
    before ended moving, as planned): judged from the commands, not from the measured
    speed, which lags the stream (more so at a reduced pace or under load)."""
    q = approved.trajectory.q_rad
    if len(q) < 2:
        return False
    planned_rad_s = float(np.abs(q[1] - q[0]).max()) * approved.trajectory.rate_hz
    return bool(ctx.notes.get("end_rad_s", 0.0) >= 0.5 * planned_rad_s)


def _at_rest_for(approved: ApprovedTrajectory, state: RobotState) -> bool:
    """A trajectory planned to continue a motion without stopping, while the arm stands
    (the motion before it was interrupted and finished from rest): its first set-points
    would jerk the arm from rest, so the step is replanned from where it stands."""
    q = approved.trajectory.q_rad
    if len(q) < 2:
        return False
    planned_rad_s = float(np.abs(q[1] - q[0]).max()) * approved.trajectory.rate_hz
    return (
        planned_rad_s > CONTINUATION_MIN_RAD_S
        and float(np.abs(state.qd_rad_s).max()) < 0.5 * planned_rad_s
    )


def run_weigh(ctx: JobContext, step: Step) -> StepGen:
    """After the lift: the load the wrist carries must lie within the grip's force window."""
    window = step.args.force
    samples: list[np.ndarray] = []
    t0 = ctx.now_s
    while ctx.now_s - t0 < SETTLE_S + AVERAGE_S:
        ctx.hold = Hold(t0, until_s=SETTLE_S + AVERAGE_S, sample_from_s=SETTLE_S, samples=samples)
        yield
        if ctx.now_s - t0 >= SETTLE_S:
            samples.append(np.array(ctx.last_state.wrench_N[:3]))
    carry = ctx.carry
    assert carry is not None  # a weighing follows the grip that set what is carried
    load = float(np.linalg.norm(np.mean(samples, axis=0) - carry.baseline_N))
    carry.load_N = load
    hi = window.max if window.max is not None else float("inf")
    if not window.min <= load <= hi:
        return Outcome.failed(
            ResultCode.NO_PART,
            f"load {load:.1f} N after lift is outside [{window.min:g}, {hi:g}] N",
        )
    return OK


def sensor_dropped(ctx: JobContext) -> str | None:
    """The gripper's sensor ('jaw sensor', 'vacuum switch') when it has read false for
    SENSOR_DEBOUNCE_S while a part is carried, else None."""
    carry = ctx.carry
    if carry is None or carry.confirm is None or ctx.last_state.inputs.get(carry.confirm):
        ctx.notes.pop("sensor_false_since", None)
        return None
    since = ctx.notes.setdefault("sensor_false_since", ctx.now_s)
    if ctx.now_s - since >= SENSOR_DEBOUNCE_S:
        return _sensor_name(ctx)
    return None


def _sensor_name(ctx: JobContext) -> str:
    return "vacuum switch" if ctx.gripper_kind == "vacuum" else "jaw sensor"


def _part_lost(ctx: JobContext) -> str | None:
    """Why the carried part is gone, judged from the jaw sensor and the wrist load."""
    carry = ctx.carry
    if carry is None:
        return None
    sensor = sensor_dropped(ctx)
    if sensor is not None:
        return f"part lost in transit: the {sensor} dropped"
    if watches_load(carry) and carry.load_N is not None:
        stream = ctx.stream
        accel, gravity = None, None
        if stream is not None and stream.tcp_accel_mps2 is not None:
            accel = stream.tcp_accel_mps2[stream.next_index - 1]  # the set-point commanded now
            gravity = stream.gravity_mps2
        load = carried_load_N(
            np.asarray(ctx.last_state.wrench_N[:3]).tolist(), carry, accel, gravity
        )
        load_lp = ctx.notes["load_lp"] = next_load_lp(ctx.notes.get("load_lp", carry.load_N), load)
        if load_lp < LOAD_LOST_FRACTION * carry.min_N:
            if carry.confirm is not None and not ctx.last_state.inputs.get(carry.confirm):
                # both see it: the sensor (still within its debounce) is the plainer cause
                return f"part lost in transit: the {_sensor_name(ctx)} dropped"
            return f"part lost in transit: the wrist load fell to {load_lp:.1f} N"
    return None


def carried_load_N(
    wrench_N: list[float],
    carry: Carry,
    accel_mps2: np.ndarray | None = None,
    gravity_mps2: np.ndarray | None = None,
) -> float:
    """The carried part's weight (N) as a wrist reading (force, base axes) shows it: the
    change from the empty tool's reading at rest. In motion (``accel_mps2``, the TCP's
    planned acceleration, and ``gravity_mps2``, both base axes) payload compensation
    takes out only the tool's weight: the tool's inertia is taken out here, and what is
    left, the part's m (g - a), is scaled back to m g. Accelerating at 5 m/s^2, a 2.5 kg
    tool's and a 2 kg carton's inertia nearly cancelled the carton's 20 N, and a part held
    fast read as lost; a lost part reads ~0 either way."""
    # plain floats: numpy's per-call cost dwarfs a 3-vector norm, and this runs every tick
    if accel_mps2 is None or gravity_mps2 is None:
        return float(carried_loads_N(wrench_N[:3], carry))
    return float(carried_loads_N(wrench_N[:3], carry, accel_mps2.tolist(), gravity_mps2.tolist()))


def carried_loads_N(
    force_N: Iterable[Any],
    carry: Carry,
    accel_mps2: Iterable[Any] | None = None,
    gravity_mps2: list[float] | None = None,
    sqrt: Callable[[Any], Any] = math.sqrt,
    maximum: Callable[[Any, Any], Any] = max,
) -> Any:
    """:func:`carried_load_N` from the force's x, y, z (and the acceleration's): three
    floats, or three arrays with one element per period and ``np.sqrt``/``np.maximum``
    (the same operations in the same order, so both give the very same bits)."""
    fx, fy, fz = force_N
    bx, by, bz = carry.baseline_N.tolist()
    if accel_mps2 is None or gravity_mps2 is None:
        return _norm(fx - bx, fy - by, fz - bz, sqrt)
    ax, ay, az = accel_mps2
    gx, gy, gz = gravity_mps2
    m = carry.tool_mass_kg
    part = _norm(fx + m * ax - bx, fy + m * ay - by, fz + m * az - bz, sqrt)
    felt = _norm(gx - ax, gy - ay, gz - az, sqrt)  # |g - a|
    g_norm = _norm(gx, gy, gz, math.sqrt)
    return part * g_norm / maximum(felt, MIN_FELT_GRAVITY * g_norm)


def _norm(x: Any, y: Any, z: Any, sqrt: Callable[[Any], Any]) -> Any:
    return sqrt(x * x + y * y + z * z)


def _planned_accel(
    ctx: JobContext, approved: ApprovedTrajectory
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The TCP's planned acceleration along ``approved`` and gravity, base axes
    (:class:`Stream`), when the load of a carried part is watched and the motions can
    tell them."""
    accel = getattr(ctx.motions, "tcp_accel_base_mps2", None)
    gravity = getattr(ctx.motions, "gravity_base_mps2", None)
    if accel is None or gravity is None or not watches_load(ctx.carry):
        return None, None
    trajectory = approved.trajectory
    return np.asarray(accel(trajectory.q_rad, trajectory.rate_hz)), np.asarray(gravity())


def watches_load(carry: Carry | None) -> bool:
    """Whether the load of the carried part is watched each period (:func:`_part_lost`)."""
    return carry is not None and carry.load_N is not None and carry.min_N > 0


def next_load_lp(load_lp: float, load_N: float) -> float:
    """One period of the low-pass on the carried load (N)."""
    return 0.9 * load_lp + 0.1 * load_N
