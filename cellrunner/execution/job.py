"""Running one job: the expanded steps in order, tick by tick, with the task's retry
policy, protective-stop hold and resume, e-stop abort, and step timeouts.

The caller owns the clock: per controller period it calls ``backend.wait_period()`` and
then :meth:`JobRunner.tick` once. ``tick`` never blocks. Phases follow PackML: execute ->
holding -> held -> unholding -> execute, or -> aborting; ``done`` at the end with
``result`` set.
"""

from __future__ import annotations

import contextlib
import enum
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cellrunner.backends.base import Safety
from cellrunner.errors import BackendError, CellrunnerError, InfeasibleError, PeerUnreachable
from cellrunner.execution import steps as behaviours
from cellrunner.execution.align import run_align
from cellrunner.execution.context import JobContext
from cellrunner.execution.force import run_force
from cellrunner.execution.lookahead import Clock, fast_forward
from cellrunner.execution.steps import Outcome, StepGen, run_motion, run_weigh
from cellrunner.execution.tool_change import run_tool_lock, run_tool_unlock
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import ON_ERROR, Step
from cellrunner.model.force_steps import FORCE_KINDS
from cellrunner.model.step import StepKind
from cellrunner.model.task import ProtectiveStopPolicy

#: the controller refuses to unlock a protective stop sooner (UR e-Series and CB3)
UNLOCK_DELAY_S = 5.0
#: tracking error is sampled every this many controller periods (125 Hz at 500 Hz)
TRACK_EVERY = 4
#: how long recovery may keep trying to unlock before the job ends with code 100
RECOVERY_TIMEOUT_S = 30.0
#: a refused unlock is tried again this often, not every period (s)
UNLOCK_RETRY_S = 0.25
#: protective stops of one step with the TCP this close (m) came at the same place
SAME_PLACE_M = 0.02
#: reconnect attempts back off from this delay, doubling to 2 s (s)
RECONNECT_FIRST_DELAY_S = 0.2

_NORMAL = Safety.NORMAL  # looked up once: tick runs every period

#: the behaviour of each step kind that is not a motion
_BEHAVIOURS = {
    **behaviours.BEHAVIOURS,
    StepKind.TOOL_LOCK: run_tool_lock,
    StepKind.ALIGN: run_align,
    StepKind.TOOL_UNLOCK: run_tool_unlock,
}


class JobPhase(enum.StrEnum):
    """Where a job is (PackML's Execute, Holding, Held; ``done`` once it ended)."""

    IDLE = "idle"
    EXECUTE = "execute"
    HOLDING = "holding"
    HELD = "held"
    DONE = "done"


class StepStatus(enum.StrEnum):
    PENDING = "pending"
    RUNNING = "running"
    OK = "ok"
    FAILED = "failed"
    SKIPPED = "skipped"


@dataclass
class StepRecord:
    """One row of the report: an expanded step and what became of it."""

    index: int
    kind: str
    name: str
    status: StepStatus = StepStatus.PENDING
    attempts: int = 0
    started_s: float | None = None
    duration_s: float = 0.0
    message: str = ""


@dataclass
class _Item:
    step: Step
    attempt: int = 1
    behaviour: str = "step"  # step | weigh | still
    resume: bool = False
    gated: bool = False  # the gate (run --step) let it start
    between: bool = False  # a retry's in-between step (not a row of its own)


@dataclass
class JobRunner:
    ctx: JobContext
    steps: list[Step]
    protective_stop: ProtectiveStopPolicy = field(default_factory=ProtectiveStopPolicy)
    wait_for_unhold: bool = False  # serve: a held job may wait for the PLC's Unhold
    on_step: Callable[[StepRecord, int], None] | None = None  # journal hook
    gate: Callable[[Step], bool] | None = None  # run --step: a step starts once gate(step) is true

    phase: JobPhase = JobPhase.IDLE
    result: ResultCode | None = None
    message: str = ""
    retries_used: int = 0
    protective_stops: int = 0
    started_s: float = 0.0
    ended_s: float = 0.0

    def __post_init__(self) -> None:
        # the task's on_error steps come last, marked; they run only after a failure
        self.on_error = [s for s in self.steps if s.macro == ON_ERROR]
        self.steps = [s for s in self.steps if s.macro != ON_ERROR]
        self._cleanup: tuple[ResultCode, str] | None = None  # the failure on_error runs after
        self._cleanup_failures: list[str] = []
        self.records = {s.index: StepRecord(s.index, s.kind, s.name) for s in self.steps}
        self._agenda: list[_Item] = [_Item(s) for s in self.steps]
        self._current: _Item | None = None
        self._gen: StepGen | None = None
        self._item_started_s = 0.0
        self._item_timeout_s = 0.0
        self._hold_since_s = 0.0
        self._hold_reason = ""
        self._unhold_requested = False  # the PLC's Unhold during a protective stop's hold
        self._stops_at: list[tuple[int, np.ndarray]] = []  # (step index, q rad) per stop
        self._requests: list[str] = []
        self._pending_end: tuple[ResultCode, str] | None = None  # after cleanup steps
        self._ticks = 0
        self._unlock_at_s = 0.0  # robot time of the next unlock attempt
        self._reconnect_why: str | None = None  # a reconnect under way, polled by tick
        self._reconnect_until = 0.0  # monotonic s
        self._reconnect_next = 0.0
        self._reconnect_delay = RECONNECT_FIRST_DELAY_S

    # ------------------------------------------------------------------ control
    @property
    def current_step(self) -> int:
        """1-based index of the step under way, 0 when none."""
        return self._current.step.index if self._current and self.phase is not JobPhase.DONE else 0

    @property
    def done(self) -> bool:
        return self.phase is JobPhase.DONE

    def request(self, what: str) -> None:
        """Queue 'hold', 'unhold' or 'abort' (from the PLC or the watchdog)."""
        self._requests.append(what)

    def start(self) -> None:
        self.ctx.read()
        self.started_s = self.ctx.now_s
        self.phase = JobPhase.EXECUTE
        self._next_item()

    # ------------------------------------------------------------------ tick
    def tick(self) -> None:
        """Advance by one controller period."""
        phase = self.phase
        if phase is JobPhase.DONE or phase is JobPhase.IDLE:
            return
        safety = self.ctx.read().safety
        self._ticks += 1
        if self._reconnect_why is not None:
            return self._reconnect()
        if safety is _NORMAL:
            if phase is JobPhase.EXECUTE and self._ticks % TRACK_EVERY == 0:
                self._track()
        elif safety is Safety.DISCONNECTED:
            return self._reconnect()
        elif safety is Safety.EMERGENCY_STOP:
            return self._finish(ResultCode.ESTOP, f"e-stop during {self._label()}")
        elif safety is Safety.FAULT:
            return self._finish(
                ResultCode.PROTECTIVE_STOP, f"controller fault during {self._label()}"
            )
        elif safety is Safety.PROTECTIVE_STOP and phase is JobPhase.EXECUTE:
            self.protective_stops += 1
            self._enter_hold("protective stop")
        while self._requests:
            self._handle_request(self._requests.pop(0))
            if self.done:
                return
        phase = self.phase
        if phase is JobPhase.EXECUTE:
            self._tick_execute()
        elif phase is JobPhase.HOLDING or phase is JobPhase.HELD:
            self._tick_held()

    def fast_forward(self, max_periods: int, until_s: float) -> int:
        """Up to ``max_periods`` periods of a streaming motion in one call, none at or
        after ``until_s`` (s); returns how many passed, 0 when the next period must run
        through :meth:`tick` (see :mod:`~cellrunner.execution.lookahead`)."""
        if (
            self.phase is not JobPhase.EXECUTE
            or self._requests
            or self._reconnect_why is not None
            or self._gen is None
            or self._current is None
            or (self.ctx.stream is None and self.ctx.hold is None)
        ):
            return 0
        clock = Clock(self._ticks, TRACK_EVERY, self._item_started_s, self._item_timeout_s, until_s)
        n = fast_forward(self.ctx, clock, max_periods)
        self._ticks += n
        return n

    def _handle_request(self, what: str) -> None:
        if what == "abort":
            self._finish(ResultCode.ABORTED_BY_PLC, f"aborted during {self._label()}")
        elif what == "hold" and self.phase is JobPhase.EXECUTE:
            self._enter_hold("hold requested")
        elif what == "unhold" and self.phase is JobPhase.HELD:
            if self._hold_reason == "protective stop":
                # the controller is still stopped: unlock it (once its delay has passed),
                # then resume; resuming now would only meet the stop again
                self._unhold_requested = True
            else:
                self._resume()

    def _enter_hold(self, reason: str) -> None:
        self.phase = JobPhase.HOLDING
        self._hold_reason = reason
        self._unhold_requested = False
        if reason == "protective stop" and self._current is not None:
            self._stops_at.append((self._current.step.index, self.ctx.last_state.q_rad.copy()))
        self._hold_since_s = self.ctx.now_s
        self._gen = None
        self.ctx.stream = self.ctx.hold = None
        self.ctx.commanded_q = None  # not streaming: no tracking error until the next set-point
        if reason != "protective stop":
            self.ctx.backend.stop_motion()
        self._log("hold", reason=reason)

    def _tick_held(self) -> None:
        state = self.ctx.last_state
        if self.phase is JobPhase.HOLDING and np.max(np.abs(state.qd_rad_s)) < 1e-3:
            self.phase = JobPhase.HELD
        if self._hold_reason != "protective stop":
            return  # a requested hold waits for unhold or abort
        held_for = self.ctx.now_s - self._hold_since_s
        automatic = (
            self.protective_stop.resume and self.protective_stops <= self.protective_stop.max
        )
        if not automatic and not self._unhold_requested:
            if not self.wait_for_unhold:
                why = (
                    "the task does not resume after protective stops"
                    if not self.protective_stop.resume
                    else f"more than {self.protective_stop.max} protective stops"
                    + self._same_place()
                )
                return self._finish(
                    ResultCode.PROTECTIVE_STOP, f"protective stop during {self._label()}: {why}"
                )
            return
        if held_for < UNLOCK_DELAY_S:
            return
        if state.safety is Safety.PROTECTIVE_STOP:
            if self.ctx.now_s < self._unlock_at_s:
                return  # bounded work: one attempt per UNLOCK_RETRY_S, polled by tick
            self._unlock_at_s = self.ctx.now_s + UNLOCK_RETRY_S
            try:
                self.ctx.backend.unlock_protective_stop()
            except BackendError as exc:
                if held_for > UNLOCK_DELAY_S + RECOVERY_TIMEOUT_S:
                    return self._finish(
                        ResultCode.PROTECTIVE_STOP, f"protective stop not recovered: {exc}"
                    )
                return
        if self.ctx.read().safety is Safety.NORMAL:
            self._resume()

    def _resume(self) -> None:
        self._log("unhold")
        self.phase = JobPhase.EXECUTE
        if self._current is not None:
            self._current.resume = True
            self._start_item(self._current)

    def _tick_execute(self) -> None:
        if self._current is None:
            return self._finish(*(self._pending_end or (ResultCode.OK, "")))
        if self.ctx.last_state.time_s - self._item_started_s > self._item_timeout_s:
            self.ctx.backend.stop_motion()
            return self._finish(ResultCode.STEP_TIMEOUT, f"{self._label()} timed out")
        if self._gen is None:  # a reconnect or hold dropped the step's generator
            self._current.resume = True
            return self._start_item(self._current)
        self.ctx.hold = None  # valid only when set by the step in this tick
        try:
            next(self._gen)
        except StopIteration as stop:
            self._on_outcome(stop.value)
        except InfeasibleError as exc:
            self._finish(ResultCode.PLANNING_FAILED, str(exc))
        except BackendError as exc:
            self._on_backend_error(exc)
        except PeerUnreachable as exc:
            self._reconnect(f"{self._label()}: {exc}")

    def _on_backend_error(self, exc: BackendError) -> None:
        """A refused command: a safety stop the state had not shown yet is handled as
        that stop; anything else means the link to the robot is in doubt."""
        safety = getattr(exc, "safety", None)
        if safety is Safety.PROTECTIVE_STOP:
            self.protective_stops += 1
            self._enter_hold("protective stop")
        elif safety is Safety.EMERGENCY_STOP:
            self._finish(ResultCode.ESTOP, f"e-stop during {self._label()}")
        else:
            self._reconnect(f"{self._label()}: {exc}")

    def _reconnect(self, why: str = "robot connection lost") -> None:
        """Bounded work polled by :meth:`tick`: one connection attempt per call when its
        backoff delay (0.2 s doubling to 2 s) is due, for at most the backend's
        ``reconnect_timeout_s`` (a backend without one gets a single attempt); then resume
        from where the arm stands, or end with 102. No call blocks for longer than one
        attempt (the backend bounds it)."""
        now = time.monotonic()
        if self._reconnect_why is None:
            self._log("reconnect", why=why)
            timeout_s = float(getattr(self.ctx.backend, "reconnect_timeout_s", 0.0))
            self._reconnect_why, self._reconnect_until = why, now + timeout_s
            self._reconnect_next, self._reconnect_delay = now, RECONNECT_FIRST_DELAY_S
            self._gen = None
            self.ctx.stream = self.ctx.hold = None
            self.ctx.commanded_q = None
        if now < self._reconnect_next:
            return
        try:
            self.ctx.backend.reconnect(timeout_s=0.0)
            failure = (
                "the robot link is still down"
                if self.ctx.read().safety is Safety.DISCONNECTED
                else None
            )
        except CellrunnerError as exc:
            failure = str(exc)
        why = self._reconnect_why
        if failure is not None:
            if time.monotonic() + self._reconnect_delay >= self._reconnect_until:
                self._reconnect_why = None
                return self._finish(ResultCode.ROBOT_CONNECTION_LOST, f"{why}; {failure}")
            self._reconnect_next = time.monotonic() + self._reconnect_delay
            self._reconnect_delay = min(2.0, self._reconnect_delay * 2)
            return
        self._reconnect_why = None
        self._log("reconnected")
        if self.phase is JobPhase.EXECUTE and self._current is not None:
            self._current.resume = True
            self._start_item(self._current)

    # ------------------------------------------------------------------ items
    def _next_item(self) -> None:
        self._current = self._agenda.pop(0) if self._agenda else None
        if self._current is not None:
            self._start_item(self._current)

    def _start_item(self, item: _Item) -> None:
        step = item.step
        self.ctx.hold = None
        self.ctx.stream = None  # a motion's generator sets it once it streams
        if (
            self.gate is not None
            and not (item.gated or item.between or item.resume)
            and item.behaviour == "step"
        ):
            self._item_timeout_s = math.inf
            self._gen = self._await_gate(item)
            return
        self._item_started_s = self.ctx.now_s
        self._item_timeout_s = self._timeout_s(item)
        record = self.records[step.index]
        if not item.between and item.behaviour == "step" and not item.resume:
            record.status, record.attempts = StepStatus.RUNNING, max(record.attempts, item.attempt)
            if record.started_s is None:
                record.started_s = self.ctx.now_s
            if self.ctx.on_step_start is not None:
                self.ctx.on_step_start(step, item.attempt)
            self._journal(record, item.attempt)
        self._log(
            "step",
            kind=step.kind,
            name=step.name,
            attempt=item.attempt,
            between=item.between or None,
            resume=item.resume or None,
        )
        if item.behaviour == "weigh":
            self._gen = run_weigh(self.ctx, step)
        elif item.behaviour == "still":
            self._gen = _stand_still(self.ctx)
        elif step.kind in FORCE_KINDS:  # a guarded line
            self._gen = run_force(self.ctx, step, resume=item.resume)
        elif step.is_motion:
            self._gen = run_motion(self.ctx, step, resume=item.resume)
        else:
            self._gen = _BEHAVIOURS[step.kind](self.ctx, step)

    def _await_gate(self, item: _Item) -> StepGen:
        """Stand still until the gate opens, then start the item (its own behaviour runs
        from the next tick on)."""
        gate = self.gate
        assert gate is not None  # started only when there is a gate
        while not gate(item.step):
            yield
        item.gated = True
        self._start_item(item)
        yield
        return behaviours.OK  # not reached: _start_item replaced this generator

    def _on_outcome(self, outcome: Outcome) -> None:
        item = self._current
        assert item is not None  # an outcome comes from the current item's behaviour
        step = item.step
        record = self.records[step.index]
        if outcome.ok:
            if not item.between and item.behaviour == "step":
                record.status = StepStatus.OK
                record.message = outcome.message or record.message  # what an align measured
                assert record.started_s is not None  # set when the step started
                record.duration_s = self.ctx.now_s - record.started_s
                self._journal(record, item.attempt)
            elif (
                item.behaviour == "weigh"
            ):  # the grip's weighing happens after its lift: its time is the grip's
                record.duration_s += self.ctx.now_s - self._item_started_s
            self._after_success(item)
            return self._next_item()
        grip = self._grip_of(item)
        if (
            grip is not None
            and outcome.code is ResultCode.NO_PART
            and grip.retry
            and item.attempt < grip.retry.attempts
        ):
            return self._retry(grip, item.attempt + 1, outcome.message)
        record = self.records[grip.index if grip is not None else step.index]
        record.status, record.message = StepStatus.FAILED, outcome.message
        record.duration_s = self.ctx.now_s - (record.started_s or self.ctx.now_s)
        self._journal(record, item.attempt)
        if grip is not None and grip.retry and outcome.code is ResultCode.NO_PART:
            # leave the part area the way the retry would, then end
            self._agenda = [_Item(b, item.attempt, between=True) for b in grip.retry.between]
            self._pending_end = (outcome.code, outcome.message)
            return self._next_item()
        self._finish(outcome.code, outcome.message)

    def _after_success(self, item: _Item) -> None:
        """A lift right after a grip with a force window: weigh the part next."""
        step = item.step
        if step.kind == StepKind.LIFT and item.behaviour == "step" and not item.between:
            grip = self._step(step.index - 1)
            if grip is not None and grip.kind == "grip" and grip.args.force is not None:
                self._agenda.insert(0, _Item(grip, item.attempt, behaviour="weigh"))

    def _grip_of(self, item: _Item) -> Step | None:
        """The grip step an item's NO_PART failure belongs to (the grip itself or its weighing)."""
        return item.step if item.step.kind == StepKind.GRIP and not item.between else None

    def _retry(self, grip: Step, attempt: int, why: str) -> None:
        self.retries_used += 1
        record = self.records[grip.index]
        record.message = f"attempt {attempt - 1} failed: {why}"
        self._log("retry", attempt=attempt, why=why)
        retry = grip.retry
        assert retry is not None  # only a grip with a retry is retried
        redo = [s for s in self.steps if retry.redo_from <= s.index <= grip.index]
        # everything after the grip not yet done; a failed weighing also redoes its lift
        rest = [
            _Item(s, attempt)
            for s in self.steps
            if s.index > grip.index
            and (self.records[s.index].status is StepStatus.PENDING or s.index == grip.index + 1)
        ]
        self._agenda = (
            [_Item(b, attempt, between=True) for b in retry.between]
            + [_Item(s, attempt) for s in redo]
            + rest
        )
        self._next_item()

    def _step(self, index: int) -> Step | None:
        return next((s for s in self.steps if s.index == index), None)

    def _timeout_s(self, item: _Item) -> float:
        step = item.step
        if step.is_motion:
            return self.ctx.step_timeout_s
        timeout = (
            getattr(step.args, "timeout", None)
            or getattr(step.args, "seconds", 0.0)
            or getattr(step.args, "pulse", 0.0)
            or 0.0
        )
        return timeout + 5.0

    # ------------------------------------------------------------------ end
    def _finish(self, code: ResultCode, message: str) -> None:
        if self.phase is JobPhase.DONE:
            return
        if self._cleanup is not None:
            return self._end_cleanup(code, message)
        if code is not ResultCode.OK and code.is_fault:
            with contextlib.suppress(BackendError):
                self.ctx.backend.stop_motion()
        if self._current is not None and code is not ResultCode.OK:
            record = self.records[self._current.step.index]
            if record.status is StepStatus.RUNNING:
                record.status, record.message = StepStatus.FAILED, message
                record.duration_s = self.ctx.now_s - (record.started_s or self.ctx.now_s)
                self._journal(record, self._current.attempt)
        for record in self.records.values():
            if record.status is StepStatus.PENDING:
                record.status = StepStatus.SKIPPED
        if code is not ResultCode.OK and self.on_error and self._arm_can_move(code):
            return self._start_cleanup(code, message)
        self._end(code, message)

    # ------------------------------------------------------------------ on_error
    def _arm_can_move(self, code: ResultCode) -> bool:
        """on_error runs only where the arm is able to move: powered, linked, no stop."""
        if code in (ResultCode.ESTOP, ResultCode.ROBOT_CONNECTION_LOST, ResultCode.PROTECTIVE_STOP):
            return False
        try:
            return self.ctx.read().safety is _NORMAL
        except (BackendError, CellrunnerError):
            return False

    def _start_cleanup(self, code: ResultCode, message: str) -> None:
        """Run the task's on_error steps (safe outputs, retreat), then end with ``code``."""
        self._cleanup = (code, message)
        self.ctx.carry = None  # cleaning up: a part still held (or lost) is not watched
        self._log("on_error", result_code=int(code), message=message)
        for s in self.on_error:
            self.records[s.index] = StepRecord(s.index, s.kind, s.name)
        self._agenda = [_Item(self.on_error[0], behaviour="still", between=True)] + [
            _Item(s) for s in self.on_error
        ]
        self._pending_end = None
        self.phase = JobPhase.EXECUTE
        self.ctx.commanded_q = None
        self._next_item()

    def _end_cleanup(self, code: ResultCode, message: str) -> None:
        """An on_error step ended (or all did, ``code`` OK). A step that fails is noted
        and the next one runs (best effort: outputs, then motions from where the arm
        stands); a fault ends cleanup. The job ends with the failure that started it;
        how on_error went is added to its message (each of its steps is journaled)."""
        assert self._cleanup is not None  # cleanup ends only after it started
        first, why = self._cleanup
        if code is not ResultCode.OK:
            if self._current is not None:
                record = self.records[self._current.step.index]
                if record.status is StepStatus.RUNNING:
                    record.status, record.message = StepStatus.FAILED, message
                    record.duration_s = self.ctx.now_s - (record.started_s or self.ctx.now_s)
                    self._journal(record, self._current.attempt)
            label = self._current.step.label if self._current is not None else "on_error"
            self._cleanup_failures.append(
                message if message.startswith("step ") else f"{label}: {message}"
            )
            # nothing moved on a failed check or a refused plan: the next step may still help
            if (not code.is_fault or code is ResultCode.PLANNING_FAILED) and self._agenda:
                self.ctx.commanded_q = None
                return self._next_item()
            if code.is_fault:
                with contextlib.suppress(BackendError):
                    self.ctx.backend.stop_motion()
        failures = self._cleanup_failures
        note = "on_error done" if not failures else f"on_error failed: {'; '.join(failures)}"
        for record in self.records.values():
            if record.status is StepStatus.PENDING:
                record.status = StepStatus.SKIPPED
        self._end(first, f"{why}; {note}" if why else note)

    def _end(self, code: ResultCode, message: str) -> None:
        self.result, self.message = code, message
        self.ended_s = self.ctx.now_s
        self.phase = JobPhase.DONE
        self._gen = None
        self.ctx.stream = self.ctx.hold = None
        self._log("job_end", result_code=int(code), message=message)

    @property
    def cycle_time_s(self) -> float:
        return (self.ended_s if self.done else self.ctx.now_s) - self.started_s

    # ------------------------------------------------------------------ helpers
    def _track(self) -> None:
        ctx = self.ctx
        if ctx.commanded_q is None:
            return
        p_cmd = ctx.motions.tcp_position_m(ctx.commanded_q)
        p_meas = ctx.motions.tcp_position_m(ctx.last_state.q_rad)
        error = math.dist(p_cmd.tolist(), p_meas.tolist())
        if error > ctx.tracking_error_m:
            ctx.tracking_error_m = error

    def _label(self) -> str:
        return self._current.step.label if self._current else "the job"

    def _same_place(self) -> str:
        """What the protective stops of the step under way say when they all came at the
        same place (the TCP within ``SAME_PLACE_M``), else nothing."""
        index = self._current.step.index if self._current else None
        here = [q for i, q in self._stops_at if i == index]
        if len(here) < 2:
            return ""
        tcp = np.array([self.ctx.motions.tcp_position_m(q) for q in here])
        spread_m = float(np.linalg.norm(tcp[:, None] - tcp[None], axis=2).max())
        if spread_m > SAME_PLACE_M:
            return ""
        which = "both" if len(here) == 2 else f"all {len(here)}"
        return (
            f", {which} with the TCP within {spread_m * 1000:.0f} mm: something there stops "
            "the arm each time"
        )

    def _journal(self, record: StepRecord, attempt: int) -> None:
        guard = self.ctx.obstacles
        if guard is not None and record.status is not StepStatus.RUNNING:
            from cellrunner.execution.obstacles import summary

            met = summary(guard.events, record.index)
            if met and met not in record.message:
                record.message = f"{record.message}; {met}" if record.message else met
        if self.on_step is not None:
            self.on_step(record, attempt)

    def _log(self, event: str, **kw: Any) -> None:
        """A structlog event bound with the step and attempt under way (the logger already
        carries cell and job_id)."""
        if self.ctx.log is not None:
            current = self._current
            fields = {
                "step": current.step.index if current else 0,
                "attempt": current.attempt if current else 0,
            }
            fields.update({k: v for k, v in kw.items() if v is not None})
            self.ctx.log.info(event, **fields)


def _stand_still(ctx: JobContext) -> StepGen:
    """Wait (at most 2 s) until the arm stands still: after a failure's stop ramp, before
    the first on_error motion."""
    t0 = ctx.now_s
    while np.max(np.abs(ctx.last_state.qd_rad_s)) > 1e-3 and ctx.now_s - t0 < 2.0:
        yield
    yield
    return behaviours.OK
