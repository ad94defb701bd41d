"""The cell: PackML states, the job queue, the journal and the job runner behind one
:class:`~cellrunner.model.cellport.CellPort`, which the PLC servers and the CLI drive.

Threading: :meth:`CellController.tick` runs on the control thread once per controller
period (after ``backend.wait_period()``, see :mod:`~cellrunner.execution.loop`); only
that thread touches the backend. The CellPort methods may be called from any thread:
they take the lock briefly, and the lock is never held across backend I/O, so a tick
that waits on the robot (a reconnect attempt, an unlock) never delays them.
:meth:`CellController.status` takes no lock at all: it returns the snapshot published
after every change. Planning a job runs on a worker thread so that ticks never block.

Every state change goes through the PackML tables of :mod:`~cellrunner.execution.packml`:
PLC commands as commands, what the robot and the job do as events.
"""

from __future__ import annotations

import contextlib
import sqlite3
import threading
import uuid
from collections.abc import Callable, Generator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np

from cellrunner.backends.base import RobotBackend, Safety
from cellrunner.errors import CellrunnerError, InputError
from cellrunner.execution.context import EventLog, Eye, JobContext, Motions, use_gripper
from cellrunner.execution.job import JobPhase, JobRunner, StepRecord
from cellrunner.execution.journal import JobRecord, JournalBackend, JournalError
from cellrunner.execution.packml import Command, Event, StateMachine, TransitionRefused
from cellrunner.model.cellport import (
    COMMANDS,
    CellStatus,
    JobResult,
    JobTicket,
    ResultListener,
)
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step, resolve_params
from cellrunner.model.gripper import gripper_channels
from cellrunner.model.load import LoadedCell, LoadedTask
from cellrunner.model.params import ParamValue
from cellrunner.model.timing import release_time_s

#: Complete is shown this long before the cell resets itself to Idle
COMPLETE_DWELL_S = 0.1

#: acting states that complete on the next tick by themselves
_SELF_COMPLETING = frozenset({S.COMPLETING, S.ABORTING, S.STOPPING, S.CLEARING, S.RESETTING})
_HOLD_STATES = frozenset({S.HOLDING, S.HELD})


@dataclass(frozen=True)
class JobPlan:
    """What the planner hands the cell for one job."""

    steps: list[Step]
    motions: Motions
    planned_cycle_time_s: float


Planner = Callable[[LoadedTask, dict[str, ParamValue], np.ndarray], JobPlan]


@dataclass(frozen=True)
class JobView:
    """What anyone reporting on a job may know of it: a frozen copy, taken on the control
    thread. ``phase`` is ``None`` while the job is being planned; ``step`` is the 1-based
    index of the step under way (0 = none); ``records`` are copies of the step rows;
    ``tracking_error_m`` the largest TCP distance (m) between commanded and measured so far;
    ``commanded_q_rad`` the set-point streamed last (None when not streaming)."""

    job_id: str
    task: str
    phase: JobPhase | None
    step: int
    planned_cycle_time_s: float | None
    records: tuple[StepRecord, ...]
    tracking_error_m: float
    retries_used: int
    cycle_time_s: float
    commanded_q_rad: np.ndarray | None
    result_code: ResultCode | None = None
    message: str = ""

    @property
    def planning(self) -> bool:
        return self.phase is None and self.result_code is None


def _view_of(
    job: _Job,
    runner: JobRunner | None,
    code: ResultCode | None = None,
    message: str = "",
    records: bool = True,
) -> JobView:
    planned = job.planned.planned_cycle_time_s if job.planned is not None else None
    if runner is None:
        return JobView(
            job.job_id, job.task.name, None, 0, planned, (), 0.0, 0, 0.0, None, code, message
        )
    ctx = runner.ctx
    rows = tuple(replace(r) for r in runner.records.values()) if records else ()
    return JobView(
        job.job_id,
        job.task.name,
        runner.phase,
        runner.current_step,
        planned,
        rows,
        ctx.tracking_error_m,
        runner.retries_used,
        runner.cycle_time_s,
        None if ctx.commanded_q is None else np.array(ctx.commanded_q),
        code if code is not None else runner.result,
        message or runner.message,
    )


@dataclass
class _Job:
    job_id: str
    task: LoadedTask
    params: dict[str, ParamValue]
    client_job_id: str
    source: str
    plan: Future[JobPlan] | None = None
    runner: JobRunner | None = None
    planned: JobPlan | None = None


class CellController:
    def __init__(
        self,
        cell: LoadedCell,
        tasks: dict[int, LoadedTask],
        backend: RobotBackend,
        journal: JournalBackend,
        planner: Planner,
        *,
        log: EventLog | None = None,
        wait_for_unhold: bool = True,
        on_step_start: Callable[[Step, int], None] | None = None,
        on_job_start: Callable[[], None] | None = None,
        gate: Callable[[Step], bool] | None = None,
        eye: Eye | None = None,
        watch: Any = None,
    ) -> None:
        self.cell, self.tasks, self.backend, self.journal = cell, tasks, backend, journal
        self.eye = eye  # the cameras, for align steps
        #: the watched zone (execution.watch.ZoneWatch) whose map every motion is checked
        #: against (SPEC 12); None: the cell is not watched
        self.watch = watch
        self.planner, self.log = planner, log
        self.wait_for_unhold = wait_for_unhold
        self.on_step_start = on_step_start
        self.on_job_start = on_job_start  # e.g. the twin's infeed brings the next part
        self.gate = gate  # run --step: each step starts once gate(step) is true
        self.sm = StateMachine(S.STOPPED)
        self._lock = threading.RLock()
        self._job: _Job | None = None
        self._last: JobResult | None = None
        self._listeners: list[ResultListener] = []
        self._entered_s = 0.0
        self._entered_tick = 0
        self._ticks = 0
        self._now_s = 0.0
        self._safety = Safety.NORMAL
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        self._actions: list[Callable[[], None]] = []  # backend work asked for by other threads
        self._recovery: Generator[None, None, None] | None = None  # Clearing's, one step a tick
        self._counters = (0, 0)
        # a result the journal has not written yet (a full disk), and its "written" event
        self._held: tuple[JobResult, threading.Event] | None = None
        self.last_runner: JobRunner | None = None  # of the last finished job (its step records)
        self._last_view: JobView | None = None
        self._status_key: tuple[object, ...] = ()
        self._status = self._snapshot()

    # ------------------------------------------------------------------ lifecycle
    def setup(self) -> None:
        """Open the journal (closing jobs a restart interrupted with 107), connect the
        robot, and reset to Idle."""
        self.journal.open()
        interrupted = self.journal.close_interrupted()
        last = interrupted[-1] if interrupted else self.journal.last_finished()
        if last is not None:
            self._last = _result_of(last)
        self._counters = self.journal.counters()
        self.backend.connect()
        self._now_s = self.backend.read_state().time_s
        with self._lock:
            self._enter_command(Command.RESET)
            self._publish()

    def shutdown(self, reason: str = "cellrunner stopped", max_ticks: int = 2000) -> None:
        """Stop safely: a running job's motion is stopped, the job closed with 107, and
        the robot left standing (bounded by ``max_ticks`` periods)."""
        job = self._job
        if job is None:
            return
        with contextlib.suppress(Exception):  # stopping is best effort; the job is closed below
            self.backend.stop_motion()
        for _ in range(max_ticks):
            state = self.backend.read_state()
            if float(np.max(np.abs(state.qd_rad_s))) < 1e-3:
                break
            self.backend.wait_period()
        with self._lock:
            self._end_job(ResultCode.INTERRUPTED, f"interrupted: {reason}", job.runner)
            self._publish()

    def held_results(self) -> list[str]:
        """The results the journal has not written yet (a full disk), for SIGTERM's report."""
        return self.journal.held()

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
        self.backend.close()
        self.journal.close()

    # ------------------------------------------------------------------ CellPort
    def status(self) -> CellStatus:
        """The snapshot published after the last change; takes no lock, never waits."""
        return self._status

    def _snapshot(self) -> CellStatus:
        state = self.sm.state
        job = self._job
        return CellStatus(
            state=int(state),
            state_name=state.display_name,
            ready=state is S.IDLE
            and job is None
            and self._held is None
            and self._safety is Safety.NORMAL,
            busy=job is not None or self._held is not None,  # a result not yet journaled
            held=state in (S.HOLDING, S.HELD),
            protective_stop=self._safety is Safety.PROTECTIVE_STOP,
            estop=self._safety is Safety.EMERGENCY_STOP,
            job_id=job.job_id if job else "",
            step_index=job.runner.current_step if job and job.runner else 0,
            last_result=self._last,
            parts_processed=self._counters[0],
            parts_defective=self._counters[1],
            obstructed=bool(self._obstruction()),
            obstruction=self._obstruction(),
        )

    def _obstruction(self) -> str:
        """Where the running job's arm waits for an obstacle ("" when it does not)."""
        job = self._job
        runner = job.runner if job is not None else None
        guard = runner.ctx.obstacles if runner is not None else None
        return guard.obstructed if guard is not None else ""

    def _publish(self) -> None:
        """Publish a new status snapshot (under the lock) when anything in it changed."""
        job = self._job
        key = (
            self.sm.state,
            job,
            self._held,
            self._safety,
            job.runner.current_step if job and job.runner else 0,
            self._last,
            self._counters,
            self._obstruction(),
        )
        if key != self._status_key:
            self._status_key = key
            self._status = self._snapshot()

    # ------------------------------------------------------------------ job views
    @property
    def busy(self) -> bool:
        """A job is under way or its end is still being shown (Starting, Completing,
        Aborting): a loop running one job ticks on while this is true."""
        return self._job is not None or self.sm.state in (S.COMPLETING, S.ABORTING, S.STARTING)

    @property
    def planning(self) -> bool:
        """A job was accepted and its plan is not picked up yet."""
        job = self._job
        return job is not None and job.runner is None

    def job_view(self, *, records: bool = True) -> JobView | None:
        """The job under way (None when there is none), with copies of its step records
        unless ``records`` is False (a per-period observer needs only the step); call on
        the control thread."""
        job = self._job
        return None if job is None else _view_of(job, job.runner, records=records)

    def streaming(self) -> Any:
        """The approved trajectory the running job streams now and the index of its next
        set-point, or None (call on the control thread)."""
        job = self._job
        runner = job.runner if job is not None else None
        stream = runner.ctx.stream if runner is not None else None
        return None if stream is None else (stream.approved, stream.next_index)

    @property
    def last_job(self) -> JobView | None:
        """The last job that ended, as it ended (its step records, result and tracking)."""
        return self._last_view

    def planned_motion_s(self, step: Step) -> float | None:
        """How long the running job's approved trajectory of ``step`` lasts (s); None for
        a step without one, or before the plan is ready."""
        job = self._job
        if job is None or job.plan is None or not job.plan.done() or job.plan.exception():
            return None
        approved = job.plan.result().motions.nominal(step)
        return None if approved is None else approved.trajectory.duration_s

    def wait_for_plan(self, timeout_s: float) -> bool:
        """Block (not the control loop's business while a job plans) until the running
        job's plan is ready or ``timeout_s`` passed; True when there is nothing to wait for."""
        job = self._job
        if job is None or job.runner is not None or job.plan is None:
            return True
        done, _ = wait([job.plan], timeout=timeout_s)
        return bool(done)

    def task_params(self, task: str | int) -> list[str] | None:
        loaded = self._task(task)
        return list(loaded.task.params) if loaded else None

    def task_param_specs(self, task: str | int) -> list[tuple[str, str, str | None]] | None:
        """(name, type, unit) of the task's params in order, for the PLC's register layout."""
        loaded = self._task(task)
        return [(n, p.type, p.unit) for n, p in loaded.task.params.items()] if loaded else None

    def start_job(
        self, task: str | int, params: dict[str, Any], client_job_id: str, source: str
    ) -> JobTicket:
        with self._lock:
            if source == "opcua" and client_job_id:
                try:
                    first = self.journal.by_client_id(source, client_job_id)
                except JournalError as exc:
                    return JobTicket("", ResultCode.REJECT_NOT_READY, f"not ready: {exc}")
                if first is not None:
                    return JobTicket(
                        first.job_id, ResultCode.OK, "the same ClientJobId again: the first job"
                    )
            loaded = self._task(task)
            if loaded is None:
                known = ", ".join(f"{n} ({t.name})" for n, t in self.tasks.items())
                return JobTicket(
                    "", ResultCode.REJECT_UNKNOWN_TASK, f"unknown task {task!r}; known: {known}"
                )
            try:
                values = resolve_params(loaded.task, params)
            except InputError as exc:
                return JobTicket("", ResultCode.REJECT_BAD_PARAMS, exc.diagnostics[0].message)
            if (
                self.sm.state is not S.IDLE
                or self._job is not None
                or self._held is not None
                or self._safety is not Safety.NORMAL
            ):
                return JobTicket(
                    "",
                    ResultCode.REJECT_NOT_READY,
                    f"not ready: state {self.sm.state.display_name}",
                )
            job = _Job(uuid.uuid4().hex[:12], loaded, values, client_job_id, source)
            try:  # journaled before it is acknowledged, or not accepted (SPEC 9)
                self.journal.begin_job(
                    job.job_id, self.cell.cell.cell, loaded.name, values, source, client_job_id
                )
            except (JournalError, sqlite3.Error) as exc:  # database away, disk full, read-only
                self._log("journal_failed", error=str(exc))
                return JobTicket(
                    "",
                    ResultCode.REJECT_NOT_READY,
                    f"not ready: the journal cannot be written: {exc}",
                )
            self._job = job
            self._enter_command(Command.START)
            self._publish()
            self._log(
                "job_accepted", job_id=job.job_id, task=loaded.name, params=values, source=source
            )
            return JobTicket(job.job_id)  # planning starts on the control thread's next tick

    def command(self, name: str) -> bool:
        if name not in COMMANDS:
            raise ValueError(f"unknown command {name!r}; known: {', '.join(COMMANDS)}")
        with self._lock:
            accepted = self._command(name)
            self._publish()
            return accepted

    def _command(self, name: str) -> bool:
        job = self._job
        runner = job.runner if job else None
        if name in ("hold", "unhold", "abort") and runner is not None and not runner.done:
            if name == "unhold" and runner.phase is not JobPhase.HELD:
                return False
            if name == "hold" and runner.phase is not JobPhase.EXECUTE:
                return False
            runner.request(name)  # the control thread acts on it at its next tick
            return True
        try:
            if name == "abort" and job is not None and runner is None:  # still planning
                self._end_job(ResultCode.ABORTED_BY_PLC, "aborted while planning")
                return True
            if name == "reset" and self._safety is Safety.EMERGENCY_STOP:
                return False  # Clear first (it finds out whether the e-stop was released)
            if name == "reset" and self.sm.state is S.ABORTED:
                return False
            if name == "reset" and job is None and self._safety is Safety.PROTECTIVE_STOP:
                # a stop latched with no job to hold (in Idle, or left by a job that ended
                # with 100): Reset is the PLC's only way to clear it
                self._actions.append(self._unlock_idle_stop)
                if self.sm.state is S.IDLE:
                    return True
            command = {
                "reset": Command.RESET,
                "clear": Command.CLEAR,
                "stop": Command.STOP,
                "abort": Command.ABORT,
                "hold": Command.HOLD,
                "unhold": Command.UNHOLD,
            }[name]
            self._enter_command(command)
            if command is Command.CLEAR:
                self._actions.append(self._start_recovery)  # on the control thread
            return True
        except (TransitionRefused, CellrunnerError):
            return False

    def add_result_listener(self, listener: ResultListener) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    # ------------------------------------------------------------------ tick
    def tick(self) -> None:
        """One controller period; call after ``backend.wait_period()``.

        Backend I/O (recovery actions, the runner's tick, starting a runner) happens
        outside the lock; the state changes it leads to are made under it."""
        with self._lock:
            self._ticks += 1
            actions, self._actions = self._actions, []
            job = self._job
        for action in actions:  # backend work other threads asked for: only this thread does it
            action()
        if self._recovery is not None:
            self._step_recovery()
        runner = job.runner if job is not None else None
        if runner is not None:
            runner.tick()
            state = runner.ctx.state or self.backend.read_state()
        else:
            state = self.backend.read_state()
            if job is not None and job.plan is None:
                if self.on_job_start is not None:
                    self.on_job_start()
                job.plan = self._pool.submit(self.planner, job.task, job.params, state.q_rad)
            elif job is not None and job.plan is not None and job.plan.done():
                runner = self._start_runner(job)
        with self._lock:
            self._now_s, self._safety = state.time_s, state.safety
            if job is not None and job is self._job and runner is not None:
                self._follow(job, runner)
            self._deliver_held()
            self._idle_transitions()
            self._publish()

    def fast_forward(self, max_periods: int, until_s: float) -> int:
        """Up to ``max_periods`` periods in one call while a job streams a motion and
        nothing else happens (the backend looks ahead; see
        :mod:`~cellrunner.execution.lookahead`), none at or after ``until_s`` (backend
        time, s). Returns how many periods passed; 0: run the next one through
        :meth:`tick` (after ``backend.wait_period()``)."""
        with self._lock:
            job = self._job
            if (
                self._actions
                or self._recovery is not None
                or job is None
                or job.runner is None
                or self.sm.state is not S.EXECUTE
                or self._safety is not Safety.NORMAL
            ):
                return 0
            runner = job.runner
        n = runner.fast_forward(max_periods, until_s)
        if n:
            state = runner.ctx.last_state
            with self._lock:
                self._ticks += n
                self._now_s, self._safety = state.time_s, state.safety
                if job is self._job:
                    self._follow(job, runner)
                self._idle_transitions()
                self._publish()
        return n

    def _start_recovery(self) -> None:
        if self._recovery is None:
            self._recovery = self._recover()

    def _step_recovery(self) -> None:
        """One bounded step of Clearing's recovery per tick; the control loop never waits
        for the arm to power up."""
        assert self._recovery is not None
        try:
            next(self._recovery)
        except StopIteration:
            self._recovery = None

    def _recover(self) -> Generator[None, None, None]:
        """Clearing (polled by :meth:`tick`): reconnect a lost link, unlock a protective stop
        the job left behind (a job that ends in one, or is aborted while held), re-arm
        after an e-stop (power, brakes), each wait bounded by the backend. The controller
        refuses an unlock within 5 s of the stop: Clear fails then, and the next Clear
        tries again."""
        error = None
        try:
            if self._safety is Safety.DISCONNECTED:
                self.backend.connect()
                yield
            if self.backend.read_state().safety is Safety.PROTECTIVE_STOP:
                self.backend.unlock_protective_stop()
                yield
            yield from self.backend.recover_from_estop_steps()
        except CellrunnerError as exc:  # e.g. the e-stop is still pressed
            error = exc
        safety = self.backend.read_state().safety
        with self._lock:
            if error is not None:
                self._log("clear_failed", error=str(error))
                if self.sm.can(Event.CLEAR_FAILED):
                    self.sm.on(Event.CLEAR_FAILED)
                    self._mark_entered()
            self._safety = safety

    def _unlock_idle_stop(self) -> None:
        """Reset with no job (on the control thread): unlock a latched protective stop. The
        controller refuses within 5 s of the stop; the next Reset tries again."""
        try:
            self.backend.unlock_protective_stop()
        except CellrunnerError as exc:
            with self._lock:
                self._log("unlock_failed", error=str(exc))
        safety = self.backend.read_state().safety
        with self._lock:
            self._safety = safety

    def _start_runner(self, job: _Job) -> JobRunner | None:
        """The planned job's runner, started (reads the robot); None when planning failed
        (the job is then ended with 103)."""
        assert job.plan is not None
        try:
            plan: JobPlan = job.plan.result()
        except Exception as exc:  # a planner bug must still close the job with a code
            message = (
                str(exc) if isinstance(exc, CellrunnerError) else f"{type(exc).__name__}: {exc}"
            )
            with self._lock:
                if job is self._job:
                    self._end_job(ResultCode.PLANNING_FAILED, message)
            return None
        job.planned = plan
        ctx = self._context(plan.motions, job.job_id)
        if self.watch is not None:
            from cellrunner.execution.obstacles import ObstacleGuard

            ctx.obstacles = ObstacleGuard(
                self.watch,
                job.task.task.on_obstacle,
                self.watch.world.limits.joint_accel_rad_s2,
            )
            job_started = getattr(self.backend, "job_started", None)
            if job_started is not None:  # the twin's intruders count from the job's start
                job_started()
        runner = JobRunner(
            ctx,
            plan.steps,
            job.task.task.on_protective_stop,
            wait_for_unhold=self.wait_for_unhold,
            gate=self.gate,
            on_step=lambda rec, attempt: self._journal_step(job, rec, attempt),
        )
        runner.start()
        return runner

    def _follow(self, job: _Job, runner: JobRunner) -> None:
        """Move the PackML state one step towards the runner's phase."""
        if job.runner is None:  # just started: Starting -> Execute
            job.runner = runner
            self.sm.state_complete()
            return self._mark_entered()
        if runner.done:
            assert runner.result is not None
            return self._end_job(runner.result, runner.message, runner)
        state, phase = self.sm.state, runner.phase
        if state is S.EXECUTE and phase in (JobPhase.HOLDING, JobPhase.HELD):
            self.sm.on(Event.HOLD_STARTED)
        elif state is S.HOLDING and phase is JobPhase.HELD:
            self.sm.state_complete()
        elif state in _HOLD_STATES and phase is JobPhase.EXECUTE:
            self.sm.on(Event.RESUMED)  # Unholding, shown for one period
        else:
            return
        self._mark_entered()

    def _idle_transitions(self) -> None:
        state = self.sm.state
        if self._entered_tick == self._ticks:
            return  # every state is visible for at least one period
        safety = self._safety
        if state is S.EXECUTE and safety is Safety.NORMAL:
            return  # the common case while a job runs: nothing to do
        if safety is Safety.EMERGENCY_STOP and self.sm.can(Event.ESTOP):
            self.sm.on(Event.ESTOP)
        elif safety is Safety.DISCONNECTED and self._job is None and self.sm.can(Event.LINK_LOST):
            self.sm.on(Event.LINK_LOST)
        elif state is S.CLEARING and self._recovery is not None:
            return  # the arm is still being re-armed
        elif state in _SELF_COMPLETING or state is S.UNHOLDING:
            self.sm.state_complete()
        elif state is S.COMPLETE and self._now_s - self._entered_s >= COMPLETE_DWELL_S:
            self._enter_command(Command.RESET)
        else:
            return
        self._mark_entered()

    def _end_job(self, code: ResultCode, message: str, runner: JobRunner | None = None) -> None:
        job = self._job
        if job is None:
            return
        retries = runner.retries_used if runner else 0
        cycle = runner.cycle_time_s if runner else 0.0
        try:
            durable = self.journal.end_job(job.job_id, code, cycle, retries, message or code.text)
        except (JournalError, sqlite3.Error) as exc:  # refused for good: the PLC still hears
            self._warn("journal_failed", job_id=job.job_id, error=str(exc))
            durable = threading.Event()
            durable.set()
        result = JobResult(
            job.job_id,
            int(code),
            message or code.text,
            cycle,
            datetime.now(UTC),
            retries,
            job.task.name,
            job.client_job_id,
            job.source,
        )
        self.last_runner = runner
        self._last_view = _view_of(job, runner, code, message or code.text)
        self._job = None
        event = Event.JOB_ABORTED if code.is_fault else Event.JOB_ENDED
        if self.sm.can(event):
            self.sm.on(event)
        elif self.sm.can(
            Event.JOB_ABORTED
        ):  # a job that ends OK in a state it cannot complete from
            self.sm.on(Event.JOB_ABORTED)
        self._mark_entered()
        self._log("job_end", job_id=job.job_id, result_code=int(code), message=message)
        self._held = (result, durable)
        if not self._deliver_held():  # a full disk: the PLC is told once it is written
            self._warn(
                "result_held",
                job_id=job.job_id,
                result_code=int(code),
                error=getattr(self.journal, "last_error", ""),
            )

    def _deliver_held(self) -> bool:
        """Tell the PLC (the result listeners, the last result) the result held until the
        journal has it; False while it is not written yet."""
        if self._held is None:
            return True
        result, durable = self._held
        if not durable.is_set():
            return False
        self._held = None
        self._last = result
        self._counters = self.journal.counters()
        self._publish()  # the snapshot a listener reads holds this result and its counters
        for listener in list(self._listeners):
            with contextlib.suppress(Exception):  # a listener must never take the cell down
                listener(result)
        return True

    # ------------------------------------------------------------------ helpers
    def _enter_command(self, command: Command) -> None:
        self.sm.command(command)
        self._mark_entered()

    def _mark_entered(self) -> None:
        self._entered_s, self._entered_tick = self._now_s, self._ticks

    def _task(self, task: str | int) -> LoadedTask | None:
        if isinstance(task, int) or (isinstance(task, str) and task.isdigit()):
            return self.tasks.get(int(task))
        return next((t for t in self.tasks.values() if t.name == task), None)

    def _context(self, motions: Motions, job_id: str) -> JobContext:
        c = self.cell.cell
        io_out, io_in = c.io.outputs, c.io.inputs
        g = c.tool.gripper
        close, open_, sensor = gripper_channels(g, io_out, io_in)
        ctx = JobContext(
            backend=self.backend,
            motions=motions,
            outputs=dict(io_out),
            inputs=dict(io_in),
            gripper_close=close,
            gripper_open=open_,
            gripper_closed_sensor=sensor,
            gripper_open_s=release_time_s(g),
            step_timeout_s=c.step_timeout,
            on_step_start=self.on_step_start,
            log=None if self.log is None else self.log.bind(job_id=job_id),
            tools=dict(c.tools),
            tool_mass_kg=c.tool.payload.mass,
            eye=self.eye,
        )
        use_gripper(ctx, g)
        return ctx

    def _journal_step(self, job: _Job, record: StepRecord, attempt: int) -> None:
        try:
            self.journal.step(
                job.job_id,
                record.index,
                record.kind,
                record.name,
                record.status,
                attempt,
                record.message,
            )
        except sqlite3.Error as exc:  # disk full: the job goes on; its row is missing a step
            self._log("journal_failed", job_id=job.job_id, error=str(exc))

    def _log(self, event: str, **kw: Any) -> None:
        if self.log is not None:
            self.log.info(event, **kw)

    def _warn(self, event: str, **kw: Any) -> None:
        if self.log is not None:
            self.log.warning(event, **kw)


def _result_of(record: JobRecord) -> JobResult:
    end = datetime.fromtimestamp(record.ended_at, UTC) if record.ended_at else None
    return JobResult(
        record.job_id,
        int(record.result_code or 0),
        record.result_text or "",
        record.cycle_time_s or 0.0,
        end,
        record.retries,
        record.task,
        record.client_job_id or "",
        record.source,
    )
