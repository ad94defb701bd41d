"""Running one job: the expanded steps in order, tick by tick, with the task's retry
policy, protective-stop hold and resume, e-stop abort, and step timeouts.

The caller owns the clock: per controller period it calls ``backend.wait_period()`` and
then :meth:`JobRunner.tick` once. ``tick`` never blocks. Phases follow PackML: execute ->
holding -> held -> unholding -> execute, or -> aborting; ``done`` at the end with
``result`` set.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from cellrunner.errors import BackendError, InfeasibleError, PeerUnreachable
from cellrunner.execution.agenda import Agenda
from cellrunner.execution.cleanup import Cleanup
from cellrunner.execution.context import JobContext
from cellrunner.execution.hold import JobHold
from cellrunner.execution.job_holding import JobHolding
from cellrunner.execution.job_records import AgendaItem, JobPhase, StepRecord, StepRows
from cellrunner.execution.lookahead import Clock, fast_forward
from cellrunner.execution.outcome import Outcome
from cellrunner.execution.reconnect import Link, Reconnect
from cellrunner.execution.retry import grip_of, retry_agenda, weighing_after
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import ON_ERROR, Step
from cellrunner.model.failure import Failure
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.robot_state import Safety
from cellrunner.model.task import ProtectiveStopPolicy

#: tracking error is sampled every this many controller periods (125 Hz at 500 Hz)
TRACK_EVERY = 4

_NORMAL = Safety.NORMAL  # looked up once: tick runs every period


@dataclass
class JobRunner(JobHolding):
    ctx: JobContext
    steps: list[Step]
    protective_stop: ProtectiveStopPolicy = field(default_factory=ProtectiveStopPolicy)
    wait_for_unhold: bool = False  # serve: a held job may wait for the PLC's Unhold
    on_step: Callable[[StepRecord, int], None] | None = None  # journal hook
    gate: Callable[[Step], bool] | None = None  # run --step: a step starts once gate(step) is true

    phase: JobPhase = JobPhase.IDLE
    result: ResultCode | None = None
    message: str = ""
    #: why the job failed, as data, when a planner refused a step (the journal keeps it)
    failure: Failure | None = None
    retries_used: int = 0
    protective_stops: int = 0
    started_s: float = 0.0
    ended_s: float = 0.0

    def __post_init__(self) -> None:
        # the task's on_error steps come last, marked; they run only after a failure
        self._cleanup = Cleanup([s for s in self.steps if s.macro_kind == ON_ERROR.kind])
        self.steps = [s for s in self.steps if s.macro_kind != ON_ERROR.kind]
        self._rows = StepRows(self.steps, self.on_step, self.ctx.obstacles)
        self.records = self._rows.records  # the report's rows, by step index
        self._agenda = Agenda(self.ctx, self._rows, self.steps, self.gate, self._log)
        self._hold = JobHold(self.protective_stop, self.wait_for_unhold)
        self._requests: list[tuple[str, HoldSource]] = []
        self._pending_end: tuple[ResultCode, str] | None = None  # after cleanup steps
        self._ticks = 0
        self._link = Reconnect()  # a reconnect under way, polled by tick
        self._link_names_step = False  # the reconnect's reason starts with the step's label

    # ------------------------------------------------------------------ control
    @property
    def current_step(self) -> int:
        """1-based index of the step under way, 0 when none."""
        return (self._agenda.step_index or 0) if self.phase is not JobPhase.DONE else 0

    @property
    def done(self) -> bool:
        return self.phase is JobPhase.DONE

    def request(self, what: str, source: HoldSource = HoldSource.PLC) -> None:
        """Queue 'hold', 'unhold' or 'abort', asked by ``source`` (the PLC, its watchdog,
        an operator over OPC UA...)."""
        self._requests.append((what, source))

    @property
    def hold(self) -> JobHold:
        """The hold under way or last (its source and reason)."""
        return self._hold

    def start(self) -> None:
        self.ctx.read()
        self.started_s = self.ctx.now_s
        self.phase = JobPhase.EXECUTE
        self._agenda.next()

    # ------------------------------------------------------------------ tick
    def tick(self) -> None:
        """Advance by one controller period."""
        phase = self.phase
        if phase is JobPhase.DONE or phase is JobPhase.IDLE:
            return
        safety = self.ctx.read().safety
        self._ticks += 1
        if self._link.active:
            return self._reconnect()
        if safety is _NORMAL:
            if phase is JobPhase.EXECUTE and self._ticks % TRACK_EVERY == 0:
                self.ctx.track()
        elif safety is Safety.DISCONNECTED:
            return self._reconnect()
        elif safety is Safety.EMERGENCY_STOP:
            return self._finish(ResultCode.ESTOP, f"e-stop during {self._agenda.label}")
        elif safety is Safety.FAULT:
            return self._finish(
                ResultCode.PROTECTIVE_STOP, f"controller fault during {self._agenda.label}"
            )
        elif safety is Safety.PROTECTIVE_STOP and phase is JobPhase.EXECUTE:
            self.protective_stops += 1
            self._enter_hold(HoldSource.PROTECTIVE_STOP)
        while self._requests:
            self._handle_request(*self._requests.pop(0))
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
            or self._link.active
            or self._agenda.gen is None
            or self._agenda.current is None
            or (self.ctx.stream is None and self.ctx.hold is None)
        ):
            return 0
        agenda = self._agenda
        clock = Clock(self._ticks, TRACK_EVERY, agenda.started_s, agenda.timeout_s, until_s)
        n = fast_forward(self.ctx, clock, max_periods)
        self._ticks += n
        return n

    def _tick_execute(self) -> None:
        agenda = self._agenda
        if agenda.current is None:
            return self._finish(*(self._pending_end or (ResultCode.OK, "")))
        if agenda.timed_out():
            self.ctx.backend.stop_motion()
            return self._finish(
                ResultCode.STEP_TIMEOUT, f"{self._agenda.label} timed out", names_step=True
            )
        if agenda.gen is None:  # a reconnect or hold dropped the step's generator
            return agenda.restart()
        self.ctx.hold = None  # valid only when set by the step in this tick
        try:
            next(agenda.gen)
        except StopIteration as stop:
            self._on_outcome(stop.value)
        except InfeasibleError as exc:
            self._finish(ResultCode.PLANNING_FAILED, str(exc), failure=exc.failure)
        except BackendError as exc:
            self._on_backend_error(exc)
        except PeerUnreachable as exc:
            self._reconnect(f"{self._agenda.label}: {exc}", names_step=True)

    def _on_backend_error(self, exc: BackendError) -> None:
        """A refused command: a safety stop the state had not shown yet is handled as
        that stop; anything else means the link to the robot is in doubt."""
        safety = getattr(exc, "safety", None)
        if safety is Safety.PROTECTIVE_STOP:
            self.protective_stops += 1
            self._enter_hold(HoldSource.PROTECTIVE_STOP)
        elif safety is Safety.EMERGENCY_STOP:
            self._finish(ResultCode.ESTOP, f"e-stop during {self._agenda.label}")
        else:
            self._reconnect(f"{self._agenda.label}: {exc}", names_step=True)

    def _reconnect(self, why: str = "robot connection lost", *, names_step: bool = False) -> None:
        """Get the robot link back (bounded, polled by :meth:`tick`; see
        :mod:`~cellrunner.execution.reconnect`), then resume from where the arm stands,
        or end with 102."""
        if not self._link.active:
            self._log("reconnect", why=why)
            self._link_names_step = names_step
            self._link.begin(why, self.ctx.backend)
            self._agenda.drop_motion()
        link = self._link.poll(self.ctx.backend, self._read_safety)
        if link is Link.LOST:
            return self._finish(
                ResultCode.ROBOT_CONNECTION_LOST,
                self._link.failure,
                names_step=self._link_names_step,
            )
        if link is Link.BACK:
            self._log("reconnected")
            if self.phase is JobPhase.EXECUTE:
                self._agenda.restart()

    # ------------------------------------------------------------------ outcomes
    def _on_outcome(self, outcome: Outcome) -> None:
        item = self._agenda.current
        assert item is not None  # an outcome comes from the current item's behaviour
        step = item.step
        if outcome.ok:
            if not item.between and item.behaviour == "step":
                self._rows.ok(step.index, item.attempt, self.ctx.now_s, outcome.message)
            elif item.behaviour == "weigh":  # after the lift: its time is the grip's
                self.records[step.index].duration_s += self.ctx.now_s - self._agenda.started_s
            weighing = weighing_after(self.steps, item)
            if weighing is not None:
                self._agenda.items.insert(0, weighing)
            return self._agenda.next()
        grip = grip_of(item)
        if (
            grip is not None
            and outcome.code is ResultCode.NO_PART
            and grip.retry
            and item.attempt < grip.retry.attempts
        ):
            return self._retry(grip, item.attempt + 1, outcome.message)
        failed = grip.index if grip is not None else step.index
        self._rows.failed(failed, item.attempt, self.ctx.now_s, outcome.message)
        if grip is not None and grip.retry and outcome.code is ResultCode.NO_PART:
            # leave the part area the way the retry would, then end
            self._pending_end = (outcome.code, outcome.message)
            return self._agenda.next(
                [AgendaItem(b, item.attempt, between=True) for b in grip.retry.between]
            )
        self._finish(outcome.code, outcome.message)

    def _retry(self, grip: Step, attempt: int, why: str) -> None:
        self.retries_used += 1
        self.records[grip.index].message = f"attempt {attempt - 1} failed: {why}"
        self._log("retry", attempt=attempt, why=why)
        self._agenda.next(retry_agenda(self.steps, self.records, grip, attempt))

    # ------------------------------------------------------------------ end
    def _finish(
        self,
        code: ResultCode,
        message: str,
        *,
        failure: Failure | None = None,
        names_step: bool = False,
    ) -> None:
        """End the job (or the on_error step under way) with ``code`` and ``message``;
        ``failure``: the planner's refusal it comes from, as data; ``names_step``: the
        message starts with the step's label (a failure that names its step does too)."""
        if self.phase is JobPhase.DONE:
            return
        names_step = names_step or (failure is not None and bool(failure.step))
        if self._cleanup.running:
            return self._end_cleanup(code, message, names_step)
        self.failure = failure
        if code is not ResultCode.OK and code.is_fault:
            with contextlib.suppress(BackendError):
                self.ctx.backend.stop_motion()
        if code is not ResultCode.OK:
            self._fail_running(message)
        self._rows.skip_pending()
        if code is not ResultCode.OK and self._cleanup.may_run(code, self._read_safety):
            return self._start_cleanup(code, message)
        self._end(code, message)

    def _start_cleanup(self, code: ResultCode, message: str) -> None:
        """Run the task's on_error steps (safe outputs, retreat), then end with ``code``."""
        self.ctx.carry = None  # cleaning up: a part still held (or lost) is not watched
        self._log("on_error", result_code=int(code), message=message)
        self._rows.add(self._cleanup.steps)
        self._pending_end = None
        self.phase = JobPhase.EXECUTE
        self.ctx.commanded_q = None
        self._agenda.next(self._cleanup.begin(code, message))

    def _end_cleanup(self, code: ResultCode, message: str, names_step: bool) -> None:
        """An on_error step ended (or all did, ``code`` OK); see
        :mod:`~cellrunner.execution.cleanup`."""
        if code is not ResultCode.OK:
            self._fail_running(message)
            label = self._agenda.label if self._agenda.current is not None else "on_error"
            if self._cleanup.note(label, code, message, names_step=names_step) and (
                self._agenda.items
            ):
                self.ctx.commanded_q = None
                return self._agenda.next()
            if code.is_fault:
                with contextlib.suppress(BackendError):
                    self.ctx.backend.stop_motion()
        self._rows.skip_pending()
        self._end(*self._cleanup.result())

    def _fail_running(self, message: str) -> None:
        """The step under way, if it is running, failed with ``message``."""
        if (item := self._agenda.current) is not None:
            self._rows.fail_running(item.step.index, item.attempt, self.ctx.now_s, message)

    def _read_safety(self) -> Safety:
        return self.ctx.read().safety

    def _end(self, code: ResultCode, message: str) -> None:
        self.result, self.message = code, message
        self.ended_s = self.ctx.now_s
        self.phase = JobPhase.DONE
        self._agenda.gen = None
        self.ctx.stream = self.ctx.hold = None
        self._log("job_end", result_code=int(code), message=message)

    @property
    def cycle_time_s(self) -> float:
        return (self.ended_s if self.done else self.ctx.now_s) - self.started_s

    # ------------------------------------------------------------------ helpers
    def _log(self, event: str, **kw: Any) -> None:
        """A structlog event bound with the step and attempt under way (the logger already
        carries cell and job_id)."""
        if self.ctx.log is not None:
            current = self._agenda.current
            fields = {
                "step": current.step.index if current else 0,
                "attempt": current.attempt if current else 0,
            }
            fields.update({k: v for k, v in kw.items() if v is not None})
            self.ctx.log.info(event, **fields)
