"""The cell: PackML states, the job queue, the journal and the job runner behind one
:class:`~cellrunner.model.cellport.CellPort`, which the PLC servers and the CLI drive.

Threading: :meth:`CellController.tick` runs on the control thread once per controller
period (after ``backend.wait_period()``); the CellPort methods may be called from any
thread and only take the lock briefly. Planning a job runs on a worker thread so that
ticks never block.
"""

from __future__ import annotations

import threading
import time
import uuid
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Callable

import numpy as np

from cellrunner.backends.base import BackendError, RobotBackend, Safety
from cellrunner.errors import CellrunnerError, InputError
from cellrunner.execution.context import JobContext, Motions
from cellrunner.execution.job import JobRunner, StepRecord
from cellrunner.execution.journal import Journal, JobRecord
from cellrunner.execution.packml import Command, StateMachine, TransitionRefused
from cellrunner.model.cellport import COMMANDS, CellStatus, JobResult, JobTicket, ResultListener
from cellrunner.model.codes import PackMLState as S, ResultCode
from cellrunner.model.expand import Step, resolve_params
from cellrunner.model.load import LoadedCell, LoadedTask
from cellrunner.model.gripper import gripper_channels
from cellrunner.model.timing import release_time_s

#: Complete is shown this long before the cell resets itself to Idle
COMPLETE_DWELL_S = 0.1

#: the PackML state shown for each phase of a running job
_PHASE_STATE = {"execute": S.EXECUTE, "holding": S.HOLDING, "held": S.HELD}
#: acting states that complete on the next tick by themselves
_SELF_COMPLETING = frozenset({S.COMPLETING, S.ABORTING, S.STOPPING, S.CLEARING, S.RESETTING})
_ABORT_STATES = frozenset({S.ABORTING, S.ABORTED})
_HOLD_STATES = frozenset({S.HOLDING, S.HELD})


@dataclass(frozen=True)
class JobPlan:
    """What the planner hands the cell for one job."""

    steps: list[Step]
    motions: Motions
    planned_cycle_time_s: float


Planner = Callable[[LoadedTask, dict, np.ndarray], JobPlan]


@dataclass
class _Job:
    job_id: str
    task: LoadedTask
    params: dict
    client_job_id: str
    source: str
    plan: Future | None = None
    runner: JobRunner | None = None
    planned: JobPlan | None = None


class CellController:
    def __init__(self, cell: LoadedCell, tasks: dict[int, LoadedTask], backend: RobotBackend,
                 journal: Journal, planner: Planner, *, log=None, wait_for_unhold: bool = True,
                 on_step_start: Callable[[Step, int], None] | None = None,
                 on_job_start: Callable[[], None] | None = None):
        self.cell, self.tasks, self.backend, self.journal = cell, tasks, backend, journal
        self.planner, self.log = planner, log
        self.wait_for_unhold = wait_for_unhold
        self.on_step_start = on_step_start
        self.on_job_start = on_job_start  # e.g. the twin's infeed brings the next part
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
        self._counters = (0, 0)
        self.last_runner: JobRunner | None = None  # of the last finished job (its step records)

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
        self._enter_command(Command.RESET)

    def shutdown(self, reason: str = "cellrunner stopped", max_ticks: int = 2000) -> None:
        """Stop safely: a running job's motion is stopped, the job closed with 107, and
        the robot left standing (bounded by ``max_ticks`` periods)."""
        with self._lock:
            job = self._job
            if job is None:
                return
            try:
                self.backend.stop_motion()
            except Exception:
                pass
        for _ in range(max_ticks):
            state = self.backend.read_state()
            if float(np.max(np.abs(state.qd_rad_s))) < 1e-3:
                break
            self.backend.wait_period()
        with self._lock:
            runner = job.runner
            self._end_job(ResultCode.INTERRUPTED, f"interrupted: {reason}", runner)

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
        self.backend.close()
        self.journal.close()

    # ------------------------------------------------------------------ CellPort
    def status(self) -> CellStatus:
        with self._lock:
            state = self.sm.state
            job = self._job
            return CellStatus(
                state=int(state), state_name=state.display_name,
                ready=state is S.IDLE and job is None and self._safety is Safety.NORMAL,
                busy=job is not None, held=state in (S.HOLDING, S.HELD),
                protective_stop=self._safety is Safety.PROTECTIVE_STOP,
                estop=self._safety is Safety.EMERGENCY_STOP,
                job_id=job.job_id if job else "",
                step_index=job.runner.current_step if job and job.runner else 0,
                last_result=self._last, parts_processed=self._counters[0],
                parts_defective=self._counters[1])

    def task_params(self, task: str | int) -> list[str] | None:
        loaded = self._task(task)
        return list(loaded.task.params) if loaded else None

    def task_param_specs(self, task: str | int) -> list[tuple[str, str, str | None]] | None:
        """(name, type, unit) of the task's params in order, for the PLC's register layout."""
        loaded = self._task(task)
        return [(n, p.type, p.unit) for n, p in loaded.task.params.items()] if loaded else None

    def start_job(self, task: str | int, params: dict, client_job_id: str, source: str) -> JobTicket:
        with self._lock:
            if source == "opcua" and client_job_id:
                first = self.journal.by_client_id(source, client_job_id)
                if first is not None:
                    return JobTicket(first.job_id, 0, "the same ClientJobId again: the first job")
            loaded = self._task(task)
            if loaded is None:
                known = ", ".join(f"{n} ({t.name})" for n, t in self.tasks.items())
                return JobTicket("", ResultCode.REJECT_UNKNOWN_TASK, f"unknown task {task!r}; known: {known}")
            try:
                values = resolve_params(loaded.task, params)
            except InputError as exc:
                return JobTicket("", ResultCode.REJECT_BAD_PARAMS, exc.diagnostics[0].message)
            if self.sm.state is not S.IDLE or self._job is not None or self._safety is not Safety.NORMAL:
                return JobTicket("", ResultCode.REJECT_NOT_READY, f"not ready: state {self.sm.state.display_name}")
            job = _Job(uuid.uuid4().hex[:12], loaded, values, client_job_id, source)
            self.journal.begin_job(job.job_id, self.cell.cell.cell, loaded.name, values, source, client_job_id)
            self._job = job
            self._enter_command(Command.START)
            self._log("job_accepted", job_id=job.job_id, task=loaded.name, params=values, source=source)
            return JobTicket(job.job_id)  # planning starts on the control thread's next tick

    def command(self, name: str) -> bool:
        if name not in COMMANDS:
            raise ValueError(f"unknown command {name!r}; known: {', '.join(COMMANDS)}")
        with self._lock:
            job = self._job
            runner = job.runner if job else None
            if name in ("hold", "unhold", "abort") and runner is not None and not runner.done:
                if name == "unhold" and runner.phase != "held":
                    return False
                if name == "hold" and runner.phase != "execute":
                    return False
                runner.request(name)
                return True
            try:
                if name == "abort" and job is not None and runner is None:  # still planning
                    self._end_job(ResultCode.ABORTED_BY_PLC, "aborted while planning")
                    return True
                if name == "reset" and self._safety is Safety.EMERGENCY_STOP:
                    return False  # Clear first (it finds out whether the e-stop was released)
                if name == "reset" and self.sm.state is S.ABORTED:
                    return False
                command = {"reset": Command.RESET, "clear": Command.CLEAR, "stop": Command.STOP,
                           "abort": Command.ABORT, "hold": Command.HOLD, "unhold": Command.UNHOLD}[name]
                self._enter_command(command)
                if command is Command.CLEAR:
                    self._actions.append(self._recover)  # on the control thread, in Clearing
                return True
            except (TransitionRefused, CellrunnerError):
                return False

    def add_result_listener(self, listener: ResultListener) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    # ------------------------------------------------------------------ tick
    def tick(self) -> None:
        """One controller period; call after ``backend.wait_period()``."""
        with self._lock:
            self._ticks += 1
            while self._actions:  # only this thread touches the backend
                self._actions.pop(0)()
            job = self._job
            runner = job.runner if job is not None else None
            if runner is not None:
                runner.tick()
                self._now_s, self._safety = self.backend.read_state().time_s, runner.ctx.state.safety
                self._follow(runner)
            else:
                state = self.backend.read_state()
                self._now_s, self._safety = state.time_s, state.safety
                if job is not None and job.plan is None:
                    if self.on_job_start is not None:
                        self.on_job_start()
                    job.plan = self._pool.submit(self.planner, job.task, job.params, state.q_rad)
                elif job is not None and job.plan.done():
                    self._start_runner(job)
            self._idle_transitions()

    def _recover(self) -> None:
        """Clearing: reconnect a lost link, re-arm after an e-stop (power, brakes)."""
        try:
            if self._safety is Safety.DISCONNECTED:
                self.backend.connect()
            self.backend.recover_from_estop()
        except (CellrunnerError, BackendError) as exc:  # e.g. the e-stop is still pressed
            self._log("clear_failed", error=str(exc))
            self.sm.force(S.ABORTED)
            self._mark_entered()
        self._safety = self.backend.read_state().safety

    def _start_runner(self, job: _Job) -> None:
        try:
            plan: JobPlan = job.plan.result()
        except CellrunnerError as exc:
            return self._end_job(ResultCode.PLANNING_FAILED, str(exc))
        except Exception as exc:  # a planner bug must still close the job with a code
            return self._end_job(ResultCode.PLANNING_FAILED, f"{type(exc).__name__}: {exc}")
        job.planned = plan
        ctx = self._context(plan.motions)
        job.runner = JobRunner(ctx, plan.steps, job.task.task.on_protective_stop,
                               wait_for_unhold=self.wait_for_unhold,
                               on_step=lambda rec, attempt: self._journal_step(job, rec, attempt))
        self.sm.state_complete()  # Starting -> Execute
        self._mark_entered()
        job.runner.start()

    def _follow(self, runner: JobRunner) -> None:
        if runner.done:
            code = runner.result
            return self._end_job(code, runner.message, runner)
        target = _PHASE_STATE.get(runner.phase)
        if target is not None and target is not self.sm.state:
            if target is S.EXECUTE and self.sm.state in _HOLD_STATES:
                self.sm.force(S.UNHOLDING)  # shown for one period
            else:
                self.sm.force(target)
            self._mark_entered()

    def _idle_transitions(self) -> None:
        state = self.sm.state
        if self._entered_tick == self._ticks:
            return  # every state is visible for at least one period
        safety = self._safety
        if state is S.EXECUTE and safety is Safety.NORMAL:
            return  # the common case while a job runs: nothing to do
        if safety is Safety.EMERGENCY_STOP and state not in _ABORT_STATES:
            self.sm.force(S.ABORTING)
        elif safety is Safety.DISCONNECTED and self._job is None and state not in _ABORT_STATES:
            self.sm.force(S.ABORTING)
        elif state in _SELF_COMPLETING:
            self.sm.state_complete()
        elif state is S.UNHOLDING:
            self.sm.force(S.EXECUTE)
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
        self.journal.end_job(job.job_id, code, cycle, retries, message or code.text)
        self._counters = self.journal.counters()
        self._last = JobResult(job.job_id, int(code), message or code.text, cycle,
                               datetime.now(timezone.utc), retries, job.task.name, job.client_job_id, job.source)
        self.last_runner = runner
        self._job = None
        if code.is_fault:
            self.sm.force(S.ABORTING)
        else:
            self.sm.force(S.COMPLETING)
        self._mark_entered()
        self._log("job_end", job_id=job.job_id, result_code=int(code), message=message)
        for listener in list(self._listeners):
            try:
                listener(self._last)
            except Exception:  # a listener must never take the cell down
                pass

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

    def _context(self, motions: Motions) -> JobContext:
        c = self.cell.cell
        io_out, io_in = c.io.outputs, c.io.inputs
        g = c.tool.gripper
        close, open_, sensor = gripper_channels(g, io_out, io_in)
        return JobContext(backend=self.backend, motions=motions, outputs=dict(io_out), inputs=dict(io_in),
                          gripper_close=close, gripper_open=open_, gripper_closed_sensor=sensor,
                          gripper_open_s=release_time_s(g),
                          step_timeout_s=c.step_timeout, on_step_start=self.on_step_start,
                          log=self._bound_log())

    def _bound_log(self):
        if self.log is None or self._job is None:
            return self.log
        return self.log.bind(job_id=self._job.job_id)

    def _journal_step(self, job: _Job, record: StepRecord, attempt: int) -> None:
        self.journal.step(job.job_id, record.index, record.kind, record.name, record.status, attempt,
                          record.message)

    def _log(self, event: str, **kw) -> None:
        if self.log is not None:
            self.log.info(event, **kw)


def _result_of(record: JobRecord) -> JobResult:
    end = datetime.fromtimestamp(record.ended_at, timezone.utc) if record.ended_at else None
    return JobResult(record.job_id, int(record.result_code or 0), record.result_text or "",
                     record.cycle_time_s or 0.0, end, record.retries, record.task,
                     record.client_job_id or "", record.source)


def run_until_done(cell: CellController, *, max_s: float, stop: threading.Event | None = None) -> None:
    """Tick ``cell`` (one backend period each) until its job ended or ``max_s`` of
    backend time passed."""
    t0 = cell.backend.read_state().time_s
    deadline_wall = time.monotonic() + max(60.0, max_s * 4)
    while cell._job is not None or cell.sm.state in (S.COMPLETING, S.ABORTING, S.STARTING):
        if stop is not None and stop.is_set():
            return
        job = cell._job
        if job is not None and job.runner is None and job.plan is not None and not job.plan.done():
            wait([job.plan], timeout=1.0)  # don't spin the physics while planning
            continue
        if cell.backend.read_state().time_s - t0 > max_s or time.monotonic() > deadline_wall:
            cell.command("abort")
            cell.backend.wait_period()
            cell.tick()
            return
        cell.backend.wait_period()
        cell.tick()
