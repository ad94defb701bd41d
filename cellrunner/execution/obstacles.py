"""A motion that meets an obstacle of the watched zone (SPEC section 12).

The rest of the motion is checked against the map before it starts and after every map
update while it runs (:class:`~cellrunner.execution.watch.ZoneWatch`). When an occupied
voxel is in the way the arm stops on its approved path: the same path, slowed to rest at
0.8 of the joints' acceleration limits (:func:`~cellrunner.model.trajectory.along_path`),
never a protective stop. It then waits, obstructed, for an image that shows the rest of
the path clear and goes on along it from where it stands (the same approved path, checked
again); with ``replan: true`` it plans from where it stands around the map (at most once a
second, ``max_replans`` times; the new plan is verified like any other, against the map
too). When the way stays blocked for ``wait`` s the step fails with 108.

Every stop, wait, replan and clear is logged (event ``obstacle``) with its time and the
blocking voxel's position, and kept on the job's notes for the journal and the report.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.execution.obstacle_guard import ObstacleGuard as ObstacleGuard  # re-exported
from cellrunner.model.codes import ResultCode
from cellrunner.model.trajectory import ApprovedTrajectory, along_path

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.model.expand import Step
    from cellrunner.model.geometry import Placed
    from cellrunner.perception.path_check import Blocked

#: a stop or a restart on the path uses this fraction of each joint's acceleration limit
RAMP_ACCEL_FRACTION = 0.8
#: replans come at most this often (s), and not before the arm has waited this long
REPLAN_EVERY_S = 1.0


def where(blocked: Blocked) -> str:
    x, y, z = blocked.voxel_m
    return f"occupied voxel at ({x:.3f}, {y:.3f}, {z:.3f}) m"


#: how a watched motion failed: (result code, message)
Failure = tuple[ResultCode, str]


@dataclass(frozen=True)
class _Go:
    """The way is clear: stream ``path`` from set-point ``pos``."""

    path: ApprovedTrajectory
    pos: int


def stream_watched(
    ctx: JobContext,
    step: Step,
    approved: ApprovedTrajectory,
    first: int,
    part_lost: Callable[[JobContext], Any],
) -> Generator[None, None, Any]:
    """Stream ``approved`` from set-point ``first`` under the watch (module docstring);
    returns None at its end, what ``part_lost(ctx)`` returned once it is not None (the
    caller's failed outcome), or a :data:`Failure` (108)."""
    from cellrunner.execution.context import Stream

    guard = ctx.obstacles
    assert guard is not None  # called only for a watched cell
    zone = guard.zone
    carried = getattr(ctx.motions, "carried_during", None)
    held: Placed | None = carried(step) if carried is not None else None
    if guard.held is not None and held is None:  # released since: it stands where the TCP is
        zone.set_down(guard.held, ctx.last_state.q_rad)
    guard.held = held
    path, pos = approved, first
    blocked = zone.check(path.trajectory.q_rad[pos:], held)
    if blocked is not None:
        guard.note(ctx, "blocked before start", blocked, step=step.index)
        result = yield from _wait(ctx, step, path, float(pos), blocked, held)
        if not isinstance(result, _Go):
            return result
        path, pos = result.path, result.pos
    while True:
        q = path.trajectory.q_rad
        follow_id = zone.follow(q, pos, held)
        stream = ctx.stream = Stream(path, pos)
        stopped_at: tuple[int, Blocked] | None = None
        while stream.next_index < len(q):
            i = stream.next_index
            ctx.backend.servo(path, i)
            ctx.commanded_q = q[i]
            stream.next_index = i + 1
            yield
            lost = part_lost(ctx)
            if lost is not None:
                return lost
            verdict = zone.verdict()
            if (
                verdict is not None
                and verdict.follow_id == follow_id
                and verdict.blocked is not None
                and verdict.blocked.index >= stream.next_index - 1
            ):
                stopped_at = (stream.next_index - 1, verdict.blocked)
                break
            zone.advance(stream.next_index)
        ctx.stream = None
        if stopped_at is None:
            zone.follow(None)
            ctx.notes["watched_path"] = path
            return None
        index, blocked = stopped_at
        guard.note(ctx, "stop", blocked, step=step.index)
        u_rest = yield from _stop_on_path(ctx, path, index, blocked.index)
        result = yield from _wait(ctx, step, path, u_rest, blocked, held)
        if not isinstance(result, _Go):
            return result
        path, pos = result.path, result.pos


def _ramp_samples(
    ctx: JobContext, path: ApprovedTrajectory, u0: float, *, stop: bool, fraction: float = 0.0
) -> int:
    """Set-points a stop (from the speed at ``u0``) or a restart at ``u0`` (up to the top
    speed of the rest of the path) takes at the ramp's acceleration."""
    assert ctx.obstacles is not None
    traj = path.trajectory
    q = traj.q_rad
    i = min(int(u0), len(q) - 2)
    if i < 0:
        return 1
    rest = q[i : i + 2] if stop else q[i:]
    speed = np.abs(np.diff(rest, axis=0)).max(axis=0) * traj.rate_hz  # rad/s
    accel = (fraction or RAMP_ACCEL_FRACTION) * ctx.obstacles.accel_rad_s2
    seconds = float(np.max(speed / accel))
    return max(1, math.ceil(seconds * traj.rate_hz))


def _stop_on_path(
    ctx: JobContext, path: ApprovedTrajectory, index: int, blocked: int
) -> Generator[None, None, float]:
    """Slow to rest along ``path`` from set-point ``index`` (commanded now), before
    set-point ``blocked`` (the first that comes too near the map) where the joints'
    full acceleration allows; returns the path position (fractional sample) where the
    arm stands."""
    last = len(path.trajectory.q_rad) - 1
    n = _ramp_samples(ctx, path, index, stop=True)
    if index + n / 2 >= blocked - 1:  # too long: as hard as the limits allow, to stop short
        hardest = _ramp_samples(ctx, path, index, stop=True, fraction=1.0)
        n = max(hardest, 2 * (blocked - 1 - index), 1)
    k = np.arange(n + 1, dtype=float)
    u = np.minimum(index + k - k * k / (2 * n), last)
    stop = along_path(path, u)
    q = stop.trajectory.q_rad
    for j in range(1, len(q)):
        ctx.backend.servo(stop, j)
        ctx.commanded_q = q[j]
        yield
    return float(u[-1])


def _resumed(ctx: JobContext, path: ApprovedTrajectory, u0: float) -> ApprovedTrajectory:
    """``path`` from rest at position ``u0``: speeding up along it, then at its pace."""
    last = len(path.trajectory.q_rad) - 1
    n = _ramp_samples(ctx, path, u0, stop=False)
    k = np.arange(n + 1, dtype=float)
    ramp = u0 + k * k / (2 * n)
    tail = np.arange(ramp[-1] + 1.0, last, 1.0)
    u = np.minimum(np.concatenate([ramp, tail, [last]]), last)
    return along_path(path, np.maximum.accumulate(u))


def _wait(
    ctx: JobContext,
    step: Step,
    path: ApprovedTrajectory,
    u_rest: float,
    blocked: Blocked,
    held: Placed | None,
) -> Generator[None, None, _Go | Failure]:
    """The arm stands at ``u_rest`` on ``path``: wait for the way to clear (then the same
    path on from there), replan around the map when the task allows, or fail with 108."""

    guard = ctx.obstacles
    assert guard is not None
    zone, policy = guard.zone, guard.policy
    since = ctx.now_s
    rest_from = min(math.ceil(u_rest - 1e-9), len(path.trajectory.q_rad) - 1)
    follow_id = zone.follow(path.trajectory.q_rad, rest_from, held)
    guard.obstructed = f"step {step.index} ({step.name}): {where(blocked)}"
    guard.note(ctx, "wait", blocked, step=step.index)
    try:
        while True:
            yield
            now = ctx.now_s
            verdict = zone.verdict()
            if verdict is not None and verdict.follow_id == follow_id and verdict.time_s > since:
                if verdict.blocked is None:
                    guard.note(ctx, "clear", None, step=step.index, waited_s=round(now - since, 3))
                    return _Go(_resumed(ctx, path, u_rest), 1)
                blocked = verdict.blocked
                guard.obstructed = f"step {step.index} ({step.name}): {where(blocked)}"
            if _replan_due(guard, now, since):
                replanned = yield from _try_replan(ctx, step, held, blocked)
                if replanned is not None:
                    return _Go(replanned, 0)
            if now - since >= policy.wait:
                message = (
                    f"{step.label}: path blocked by an obstacle not in the cell file "
                    f"({where(blocked)}) for {policy.wait:g} s"
                    + (f" after {guard.replans} replan(s)" if policy.replan else "")
                )
                guard.note(ctx, "blocked", blocked, step=step.index)
                return ResultCode.PATH_BLOCKED, message
    finally:
        guard.obstructed = ""
        zone.follow(None)


def _replan_due(guard: ObstacleGuard, now_s: float, since_s: float) -> bool:
    """Whether to replan now (s, job clock): the task allows it, replans are left, and
    REPLAN_EVERY_S has passed since the wait began (``since_s``) and since the last replan."""
    policy = guard.policy
    return (
        policy.replan
        and guard.replans < policy.max_replans
        and now_s - since_s >= REPLAN_EVERY_S
        and now_s - guard.last_replan_s >= REPLAN_EVERY_S
    )


def _try_replan(
    ctx: JobContext, step: Step, held: Placed | None, blocked: Blocked
) -> Generator[None, None, ApprovedTrajectory | None]:
    """One replan around the map from the measured joints, counted and journalled (with
    its planning time, s); the new path, or None when none passes."""
    guard = ctx.obstacles
    assert guard is not None
    guard.replans += 1
    guard.last_replan_s = ctx.now_s
    t0 = time.perf_counter()
    if guard.zone.replan_in_background:  # the control loop ticks on meanwhile
        replanned = yield from _replan_while_ticking(ctx, step, held)
    else:
        replanned = _replan(ctx, step, held, ctx.last_state.q_rad)
    plan_s = round(time.perf_counter() - t0, 4)
    if replanned is not None:
        guard.note(ctx, "replan", blocked, step=step.index, replans=guard.replans, plan_s=plan_s)
        return replanned
    guard.note(
        ctx,
        "replan failed",
        blocked,
        step=step.index,
        replans=guard.replans,
        plan_s=plan_s,
        why=guard.why_not,
    )
    return None


def _replan_while_ticking(
    ctx: JobContext, step: Step, held: Placed | None
) -> Generator[None, None, ApprovedTrajectory | None]:
    """:func:`_replan` on a worker thread, yielding a tick at a time until it is done."""
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(1, thread_name_prefix="replan")
    try:
        future = pool.submit(_replan, ctx, step, held, ctx.last_state.q_rad)
        while not future.done():
            yield
        return future.result()
    finally:  # an abort while planning leaves the plan to finish unread
        pool.shutdown(wait=False)


#: the map's cubes grown by these in turn until a plan passes the path check (see _replan)
REPLAN_GROWTH = (1.0, 1.25, 1.5, math.sqrt(3.0))


def _replan(
    ctx: JobContext, step: Step, held: Placed | None, q_rad: np.ndarray
) -> ApprovedTrajectory | None:
    """A verified plan from ``q_rad`` (where the arm stands) around the map, clear of it
    now; None when there is none. The planner's cubes and the path check's grown solids
    differ near a solid's edges: a plan the path check refuses is planned again around
    cubes grown further (:data:`REPLAN_GROWTH`, up to sqrt(3), which covers what the
    path check calls near)."""
    assert ctx.obstacles is not None
    zone = ctx.obstacles.zone
    for scale in REPLAN_GROWTH:
        try:
            new = ctx.motions.replan(
                step,
                q_rad,
                carrying=ctx.carry is not None,
                obstacles=zone.obstacles(scale, leaving=q_rad, held=held),
            )
        except InfeasibleError as exc:
            if scale == 1.0:
                ctx.obstacles.why_not = str(exc)
            continue
        blocked = zone.check(new.trajectory.q_rad, held)
        if blocked is None:
            return new
        at_goal = zone.check(new.trajectory.q_rad[-1:], held)
        if at_goal is not None:  # no way round: the step's goal itself is within the padding
            ctx.obstacles.why_not = f"its goal is within the padding of the map: {where(at_goal)}"
            return None
        ctx.obstacles.why_not = f"the new plan meets the map: {where(blocked)}"
    return None
