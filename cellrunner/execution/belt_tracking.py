"""Running a tracked stretch (SPEC section 13): from ``track`` to ``untrack``, as one
approved trajectory.

At ``track`` the engine takes the oldest part the eye latched and the belt's measured
speed (:mod:`.belt_watch`), makes the stretch's commanded motion for them (the ramp onto
the part, the still plan of the tracked steps with the part's travel added, the ramp
back: :mod:`cellrunner.planning.tracked_approval`), has it checked by ``check``'s own
proof and sealed, waits for the part to reach the start, and streams it. The grip's own
behaviour (baseline, close, confirm) runs alongside while the arm keeps following the
belt; the tracked steps and ``untrack`` then count as done.

- A belt above its ``speed_max``, or a part past the latest start the window allows: the
  part is let go, the job ends 109 before the arm moves onto the belt.
- A belt whose travel leaves the measured speed by more than ``BELT_TOLERANCE_M`` while
  the arm follows it (stopped, slipped, an encoder jump): a controlled stop, 100; the arm
  does not chase it.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.execution.belt_follow import FOLLOW_FROM_M, BeltFollower
from cellrunner.execution.outcome import OK, Outcome, StepGen
from cellrunner.model.codes import ResultCode

if TYPE_CHECKING:
    from collections.abc import Callable, Generator

    from cellrunner.execution.belt_watch import BeltView
    from cellrunner.execution.context import JobContext
    from cellrunner.model.expand import Step
    from cellrunner.planning.task_plan import TaskPlan
    from cellrunner.planning.timing import MotionLimits
    from cellrunner.planning.tracked_approval import TrackedRun

#: a measured speed this far above speed_max (relative) is still taken as speed_max's
SPEED_TOLERANCE = 0.02
#: the belt's travel may leave the line of its measured speed by this much while the arm
#: follows it, m, before the arm stops
BELT_TOLERANCE_M = 0.005
#: the stretch starts this many periods after it was made (the part's offset then)
LEAD_PERIODS = 2
#: on a backend whose time runs on by itself (``clock_runs_on``: the controller), the
#: stretch is made on a worker thread for a start this far ahead at least, s; made too
#: late, it is made again with twice the time it took (at most ``BUILD_ATTEMPTS`` times)
BUILD_BUDGET_S = 0.3
BUILD_ATTEMPTS = 3
#: the grip must have confirmed this long after its planned end, s (the jaws' travel)
GRIP_SLACK_S = 0.1
#: after the last set-point the arm must stand this close to it, rad, within ARRIVE_S
ARRIVE_RAD = np.radians(1.0)
ARRIVE_S = 1.0
#: notes key: the step indices a tracked stretch ran (the runner skips them)
DONE_KEY = "belt_done"


def run_track(ctx: JobContext, step: Step) -> StepGen:
    """The behaviour of a ``track`` step; see the module docstring."""
    from cellrunner.planning.tracked_approval import stretch_piece

    name = step.args.conveyor
    ready = _ready(ctx, name)
    if isinstance(ready, Outcome):
        return ready
    plan, view = ready
    conveyor = plan.world.loaded.cell.conveyors[name]
    piece = stretch_piece(plan, step.index, float(ctx.backend.rate_hz))
    if piece is None:
        return Outcome.failed(ResultCode.PLANNING_FAILED, f"conveyor {name!r}: no tracked steps")
    t0 = ctx.now_s
    while not view.latched_m or view.speed_mps() is None:
        if ctx.now_s - t0 >= ctx.step_timeout_s:
            return Outcome.failed(
                ResultCode.STEP_TIMEOUT,
                f"conveyor {name!r}: no part crossed the eye within {ctx.step_timeout_s:g} s",
            )
        yield
    latched = view.latched_m.popleft()
    eye_to_frame = float(conveyor.eye_to_frame)

    def offset_m() -> float:
        assert view.travel_m is not None
        return view.travel_m - latched - eye_to_frame

    speed = view.speed_mps()
    assert speed is not None
    v_max = float(conveyor.speed_max)
    if speed > v_max * (1 + SPEED_TOLERANCE):
        return Outcome.failed(
            ResultCode.PART_LEFT_WINDOW,
            f"conveyor {name!r}: the belt runs at {speed:.3f} m/s, above its speed_max "
            f"{v_max:g} m/s (the pick is proved up to it): the part at {offset_m():+.3f} m is "
            "let go",
        )
    stretch = _Stretch(ctx, name, plan, step, conveyor, piece, min(max(speed, 0.0), v_max))
    made = yield from stretch.make(offset_m)
    if isinstance(made, Outcome):
        return made
    run, t_send = made
    # the arm stands over the frame until then; a belt that leaves its measured speed
    # meanwhile is followed from there (the stretch starts when the part reaches it)
    follow: BeltFollower | None = None
    while ctx.now_s < t_send - stretch.dt / 2:
        yield
        if abs(stretch.drift_m(offset_m)) > FOLLOW_FROM_M:
            follow = BeltFollower(run, plan.world.limits, 0.0, 0.0)
            break
    return (yield from _stream(ctx, step, run, (view, offset_m), plan.world.limits, follow))


def _ready(ctx: JobContext, name: str) -> Outcome | tuple[TaskPlan, BeltView]:
    """The job's plan and the belt's view, or why this job cannot follow the belt."""
    from cellrunner.planning.task_plan import TaskPlan

    plan = ctx.motions
    view = ctx.belts.belts.get(name) if ctx.belts is not None else None
    if not isinstance(plan, TaskPlan):
        return Outcome.failed(
            ResultCode.PLANNING_FAILED,
            f"conveyor {name!r}: a tracked stretch runs at full pace only (the belt does not "
            "slow down with the job's speed)",
        )
    if view is None or view.travel_m is None:
        return Outcome.failed(
            ResultCode.PLANNING_FAILED,
            f"conveyor {name!r}: this backend cannot measure the belt (no encoder reading), "
            "so it cannot follow it",
        )
    return plan, view


class _Stretch:
    """Making one tracked stretch for a part at a measured ``speed``: in time for the part,
    off the control thread where the backend's time runs on, and again with more lead
    when it was made too late."""

    def __init__(
        self,
        ctx: JobContext,
        name: str,
        plan: TaskPlan,
        step: Step,
        conveyor: Any,
        piece: Any,
        speed: float,
    ) -> None:
        self.ctx, self.name, self.plan, self.step = ctx, name, plan, step
        self.conveyor, self.piece, self.speed = conveyor, piece, speed
        self.dt = 1.0 / float(ctx.backend.rate_hz)
        self.s_made, self.t_made = 0.0, ctx.now_s

    def drift_m(self, offset_m: Callable[[], float]) -> float:
        """How far the belt's travel is off the line of the speed the stretch is made for
        (m, positive: ahead of it)."""
        return offset_m() - (self.s_made + self.speed * (self.ctx.now_s - self.t_made))

    def belt_off(self, offset_m: Callable[[], float]) -> Outcome | None:
        """A controlled stop when the belt left the line of its measured speed before the
        stretch started (stopped or jumped); None while it keeps it."""
        drift = self.drift_m(offset_m)
        if abs(drift) <= BELT_TOLERANCE_M:
            return None
        return Outcome.failed(
            ResultCode.PROTECTIVE_STOP,
            f"conveyor {self.name!r}: the belt is {drift * 1000:+.1f} mm off its measured "
            f"{self.speed:.3f} m/s before the {self.piece.what} started (stopped or jumped): "
            "the arm stays where it is",
        )

    def make(self, offset_m: Callable[[], float]) -> Generator[None, None, Any]:
        """The approved stretch and when its first set-point is sent, or the outcome
        that ends the job."""
        from cellrunner.planning.belt_ramp import nominal_start_m, ramp_bounds
        from cellrunner.planning.tracked_approval import approve_tracked
        from cellrunner.planning.tracking import latest_fitting_start_m

        ctx, name, conveyor, piece, speed, dt = (
            self.ctx,
            self.name,
            self.conveyor,
            self.piece,
            self.speed,
            self.dt,
        )
        lo, hi = (float(w) for w in conveyor.window)
        earliest = nominal_start_m(speed, lo, ramp_bounds(conveyor.path))
        runs_on = bool(getattr(ctx.backend, "clock_runs_on", False))
        budget_s = BUILD_BUDGET_S if runs_on else 0.0
        for _attempt in range(BUILD_ATTEMPTS):
            # the part's offset when the first set-point is reached: it is sent ``lead``
            # periods from now (the earliest start, or once the stretch is made) and reached
            # one later
            lead = max(LEAD_PERIODS, int(np.ceil(budget_s / dt)))
            if speed > 0 and offset_m() + speed * (lead + 1) * dt < earliest:
                lead = int(np.ceil((earliest - offset_m()) / (speed * dt))) - 1
            start = offset_m() + speed * (lead + 1) * dt
            t_send = ctx.now_s + lead * dt
            latest = latest_fitting_start_m(conveyor, piece.duration_s, speed)
            if latest is None or start > latest + 1e-9:
                return Outcome.failed(
                    ResultCode.PART_LEFT_WINDOW,
                    f"conveyor {name!r}: the part is at {offset_m():+.3f} m from the frame at "
                    f"{speed:.3f} m/s; the {piece.what} must start by "
                    + ("-" if latest is None else f"{latest:+.3f} m")
                    + f" to end in the window [{lo:+.3f}, {hi:+.3f}] m: the part is let go",
                )
            self.t_made, self.s_made = ctx.now_s, offset_m()

            def make(start: float = start) -> TrackedRun | str:
                return approve_tracked(self.plan, self.step.index, conveyor, piece, speed, start)

            made = _MadeOffThread(make)
            if not runs_on:
                made.join()  # the twin's time waits for the engine
            while not made.done():  # the controller's does not: keep watching the belt
                yield
                stopped = self.belt_off(offset_m)
                if stopped is not None:
                    made.join()
                    return stopped
            run = made.result()
            if isinstance(run, str):
                return Outcome.failed(
                    ResultCode.PLANNING_FAILED,
                    f"conveyor {name!r}: the {piece.what} at {speed:.3f} m/s from {start:+.3f} m "
                    f"is refused: {run}",
                )
            if ctx.now_s < t_send - dt / 2:
                return run, t_send
            budget_s = 2 * (ctx.now_s - self.t_made) + dt  # made too late: again, more lead
        return Outcome.failed(
            ResultCode.PLANNING_FAILED,
            f"conveyor {name!r}: the {piece.what} could not be made before the part reached "
            f"its start in {BUILD_ATTEMPTS} attempts",
        )


class _MadeOffThread:
    """``make()`` run on a worker thread, so the control loop keeps its period while a
    tracked stretch is made (an IK solution and a collision check per set-point)."""

    def __init__(self, make: Callable[[], Any]) -> None:
        self._value: Any = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(
            target=self._run, args=(make,), daemon=True, name="belt-stretch"
        )
        self._thread.start()

    def _run(self, make: Callable[[], Any]) -> None:
        try:
            self._value = make()
        except BaseException as exc:  # handed to the control thread, raised there
            self._error = exc

    def done(self) -> bool:
        return not self._thread.is_alive()

    def join(self) -> None:
        self._thread.join()

    def result(self) -> Any:
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value


def _stream(
    ctx: JobContext,
    step: Step,
    run: TrackedRun,
    belt: tuple[BeltView, Callable[[], float]],
    limits: MotionLimits,
    follow: BeltFollower | None,
) -> StepGen:
    """Stream the stretch, one set-point a period while the belt keeps the speed it was
    made for (catching up by one more a period when the engine fell behind the backend's
    time), along the belt's travel once it does not (:mod:`.belt_follow`); the grip's
    behaviour alongside."""
    from cellrunner.execution.steps import part_lost_outcome
    from cellrunner.model.step_kinds import kind_of

    view, offset_m = belt
    approved = run.approved
    q = approved.trajectory.q_rad
    rate_hz = approved.trajectory.rate_hz
    conveyor = step.args.conveyor
    steps = {s.index: s for s in _job_steps(ctx)}
    grip = next(((i, a, b) for i, a, b in run.spans if steps[i].kind == "grip"), None)
    grip_gen: StepGen | None = None
    grip_done: Outcome | None = None if grip is not None else OK
    slack = round(GRIP_SLACK_S * rate_hz)
    t_start, s_start = ctx.now_s, float(offset_m())
    i = -1
    while (i < len(q) - 1) if follow is None else not follow.at_end:
        if follow is None:
            # one set-point a period; behind the backend's time (periods the engine missed
            # on a controller whose time runs on), two, until the arm is back with the part
            behind = round((ctx.now_s - t_start) * rate_hz) > i + 1
            i = min(len(q) - 1, i + (2 if behind else 1))
            ctx.backend.servo(approved, i)
            ctx.commanded_q = q[i]
        else:
            command = follow.next(float(offset_m()), ctx.now_s)
            if abs(command.lag_m) > BELT_TOLERANCE_M and not command.late:
                ctx.backend.stop_motion()
                return Outcome.failed(
                    ResultCode.PROTECTIVE_STOP,
                    f"conveyor {conveyor!r}: the belt is {command.lag_m * 1000:+.1f} mm off "
                    f"its measured {run.speed_mps:.3f} m/s {command.u / rate_hz:.2f} s into "
                    "the tracked stretch, more than the arm can follow (stopped at once or "
                    "jumped): controlled stop",
                )
            ctx.backend.servo(command.trajectory, command.index)
            ctx.commanded_q = command.trajectory.trajectory.q_rad[command.index]
            i = int(command.u)
        if grip is not None and grip_gen is None and i >= grip[1]:
            grip_gen = kind_of("grip").run(ctx, steps[grip[0]], False)
        yield
        if view.speed_mps() is None:  # not measured any more (a PLC's count went stale)
            ctx.backend.stop_motion()
            return Outcome.failed(
                ResultCode.PROTECTIVE_STOP,
                f"conveyor {conveyor!r}: the belt is not measured any more {i / rate_hz:.2f} s "
                "into the tracked stretch (its encoder's count stopped coming): controlled stop",
            )
        if follow is None:
            drift = float(offset_m()) - (s_start + run.speed_mps * (ctx.now_s - t_start))
            if abs(drift) > FOLLOW_FROM_M:  # slowed, stopped or jumped: follow its travel
                follow = BeltFollower(run, limits, float(i), 1.0)
        if grip_gen is not None and grip_done is None:
            try:
                next(grip_gen)
            except StopIteration as end:
                grip_done = end.value
            ctx.hold = None  # the arm follows the belt, it does not hold still
            if grip_done is not None and not grip_done.ok:
                ctx.backend.stop_motion()
                return grip_done
        if grip is not None and grip_done is None and i >= grip[2] + slack:
            ctx.backend.stop_motion()
            return Outcome.failed(
                ResultCode.NO_PART,
                f"the grip did not confirm within its {(grip[2] - grip[1]) / rate_hz:.2f} s on "
                "the belt",
            )
        lost = part_lost_outcome(ctx)
        if lost is not None:
            return lost
    ctx.notes[DONE_KEY] = {i for i, _, _ in run.spans} | {run.untrack_index}
    t_end = ctx.now_s
    while float(np.abs(np.asarray(ctx.last_state.q_rad) - q[-1]).max()) > ARRIVE_RAD:
        if ctx.now_s - t_end >= ARRIVE_S:
            return Outcome.failed(
                ResultCode.STEP_TIMEOUT,
                f"the arm did not arrive at the end of the tracked stretch within {ARRIVE_S:g} s",
            )
        ctx.backend.servo(approved, len(q) - 1)
        yield
    return OK


def _job_steps(ctx: JobContext) -> list[Step]:
    plan = ctx.motions
    return [row.step for row in getattr(plan, "rows", [])]
