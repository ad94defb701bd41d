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

import threading
import uuid
from collections.abc import Callable
from typing import Any

from cellrunner.backends.base import RobotBackend
from cellrunner.errors import CellrunnerError
from cellrunner.execution.cell_states import CellStates
from cellrunner.execution.cell_views import CellViews
from cellrunner.execution.context import QUIET, EventLog, Eye
from cellrunner.execution.job import JobRunner
from cellrunner.execution.job_book import JobBook
from cellrunner.execution.job_launch import JobLauncher, PlanRefused
from cellrunner.execution.job_records import JobPhase
from cellrunner.execution.job_view import (
    Job,
    JobView,
    view_of,
)
from cellrunner.execution.journal import JournalBackend
from cellrunner.execution.packml import Command, Event, TransitionRefused
from cellrunner.execution.planner import Planner
from cellrunner.execution.plc_encoders import Registers
from cellrunner.execution.recovery import Recovery, stop_and_stand, unlock_idle_stop
from cellrunner.execution.task_menu import TaskMenu
from cellrunner.model.cellport import (
    COMMANDS,
    JobSource,
    JobTicket,
    ResultListener,
)
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step
from cellrunner.model.failure import Failure
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.load import LoadedCell, LoadedTask
from cellrunner.model.robot_state import RobotState, Safety

#: the PLC's commands that go to the state machine as they are
_COMMAND_OF = {
    "reset": Command.RESET,
    "clear": Command.CLEAR,
    "stop": Command.STOP,
    "abort": Command.ABORT,
    "hold": Command.HOLD,
    "unhold": Command.UNHOLD,
}


class CellController(CellViews):
    """One cell: PackML, the job queue, the journal, the job runner; see the module
    docstring."""

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
        self._menu = TaskMenu(tasks)
        self.log = log or QUIET
        self.on_job_start = on_job_start  # e.g. the twin's infeed brings the next part
        self._book = JobBook(journal, cell.cell.cell, log, publish=self._publish)
        self._launcher = JobLauncher(
            cell,
            backend,
            self._book,
            planner,
            log=log,
            wait_for_unhold=wait_for_unhold,
            on_step_start=on_step_start,
            gate=gate,
            eye=eye,
            watch=watch,
        )
        self.states = CellStates()
        self._lock = threading.RLock()
        self._job: Job | None = None
        self._safety = Safety.NORMAL
        self._actions: list[Callable[[], None]] = []  # backend work asked for by other threads
        self._recovery = Recovery()  # Clear's, one step a tick
        self.last_runner: JobRunner | None = None  # of the last finished job (its step records)
        self._last_view: JobView | None = None
        self._status_key: tuple[object, ...] = ()
        self._status = self._snapshot()
        self._robot: RobotState | None = None  # the last measurement a tick read

    # ------------------------------------------------------------------ lifecycle
    def setup(self) -> None:
        """Open the journal (closing jobs a restart interrupted with 107), connect the
        robot, and reset to Idle."""
        self._book.open()
        self.backend.connect()
        self.states.now_s = self.backend.read_state().time_s
        with self._lock:
            self.states.command(Command.RESET)
            self._publish()

    def shutdown(self, reason: str = "cellrunner stopped", max_ticks: int = 2000) -> None:
        """Stop safely: a running job's motion is stopped, the job closed with 107, and
        the robot left standing (bounded by ``max_ticks`` periods)."""
        job = self._job
        if job is None:
            return
        stop_and_stand(self.backend, max_ticks)
        with self._lock:
            self._end_job(ResultCode.INTERRUPTED, f"interrupted: {reason}", job.runner)
            self._publish()

    def read_plc_encoders(self, registers: Callable[[], Registers]) -> None:
        """``serve``: the cell's ``source: plc`` belts are measured from ``registers()``,
        the PLC server's (see :mod:`~cellrunner.execution.plc_encoders`); call before the
        control loop runs."""
        self._launcher.read_plc_encoders(registers)

    def close(self) -> None:
        self._launcher.close()
        self.backend.close()
        self._book.close()

    # ------------------------------------------------------------------ CellPort
    def _publish(self) -> None:
        """Publish a new status snapshot (under the lock) when anything in it changed."""
        key = self._status_inputs()
        if key != self._status_key:
            self._status_key = key
            self._status = self._snapshot()

    def start_job(
        self, task: str | int, params: dict[str, Any], client_job_id: str, source: str | JobSource
    ) -> JobTicket:
        requester = JobSource.of(source)
        source = requester.name
        with self._lock:
            first = self._book.first_of(requester, client_job_id)
            if first is not None:
                return first
            admitted = self._menu.admit(task, params)
            if isinstance(admitted, JobTicket):
                return admitted  # an unknown task, bad params
            loaded, values = admitted
            if (
                self.states.state is not S.IDLE
                or self._job is not None
                or self._book.holding
                or self._safety is not Safety.NORMAL
            ):
                return JobTicket(
                    "",
                    ResultCode.REJECT_NOT_READY,
                    f"not ready: state {self.states.state.display_name}",
                )
            job = Job(uuid.uuid4().hex[:12], loaded, values, client_job_id, source)
            refused = self._book.begin(job)  # journaled before it is acknowledged (SPEC 9)
            if refused is not None:
                return refused
            self._job = job
            self.states.command(Command.START)
            self._publish()
            self.log.info(
                "job_accepted", job_id=job.job_id, task=loaded.name, params=values, source=source
            )
            return JobTicket(job.job_id)  # planning starts on the control thread's next tick

    def command(self, name: str, source: HoldSource = HoldSource.PLC) -> bool:
        if name not in COMMANDS:  # ValueError: CellPort.command's contract for an unknown name
            raise ValueError(f"unknown command {name!r}; known: {', '.join(COMMANDS)}")
        with self._lock:
            accepted = self._command(name, source)
            self._publish()
            return accepted

    def _command(self, name: str, source: HoldSource) -> bool:
        job = self._job
        runner = job.runner if job else None
        if name in ("hold", "unhold", "abort") and runner is not None and not runner.done:
            if name == "unhold" and runner.phase is not JobPhase.HELD:
                return False
            if name == "hold" and runner.phase is not JobPhase.EXECUTE:
                return False
            runner.request(name, source)  # the control thread acts on it at its next tick
            return True
        try:
            if name == "abort" and job is not None and runner is None:  # still planning
                self._end_job(ResultCode.ABORTED_BY_PLC, "aborted while planning")
                return True
            if name == "reset" and self._safety is Safety.EMERGENCY_STOP:
                return False  # Clear first (it finds out whether the e-stop was released)
            if name == "reset" and self.states.state is S.ABORTED:
                return False
            if name == "reset" and job is None and self._safety is Safety.PROTECTIVE_STOP:
                # a stop latched with no job to hold (in Idle, or left by a job that ended
                # with 100): Reset is the PLC's only way to clear it
                self._actions.append(lambda: self._recovered(*unlock_idle_stop(self.backend)))
                if self.states.state is S.IDLE:
                    return True
            command = _COMMAND_OF[name]
            self.states.command(command)
            if command is Command.CLEAR:
                disconnected = self._safety is Safety.DISCONNECTED
                self._actions.append(lambda: self._recovery.start(self.backend, disconnected))
            return True
        except (TransitionRefused, CellrunnerError):
            return False

    def add_result_listener(self, listener: ResultListener) -> Callable[[], None]:
        with self._lock:
            self._book.listeners.append(listener)
        listeners = self._book.listeners
        return lambda: listeners.remove(listener) if listener in listeners else None

    # ------------------------------------------------------------------ tick
    def tick(self) -> None:
        """One controller period; call after ``backend.wait_period()``.

        Backend I/O (recovery actions, the runner's tick, starting a runner) happens
        outside the lock; the state changes it leads to are made under it."""
        with self._lock:
            self.states.ticks += 1
            actions, self._actions = self._actions, []
            job = self._job
        for action in actions:  # backend work other threads asked for: only this thread does it
            action()
        if self._recovery.active and (recovered := self._recovery.step()) is not None:
            self._recovered(*recovered, failed=Event.CLEAR_FAILED)
        runner = job.runner if job is not None else None
        if runner is not None:
            runner.tick()
            state = runner.ctx.state or self.backend.read_state()
        else:
            state = self.backend.read_state()
            self._launcher.note_belts(state)  # a job's context notes them while it runs
            if job is not None and job.plan is None:
                if self.on_job_start is not None:
                    self.on_job_start()
                self._launcher.plan(job, state.q_rad)
            elif job is not None and job.plan is not None and job.plan.done():
                started = self._launcher.start(job)
                if isinstance(started, PlanRefused):  # the job ends with 103
                    with self._lock:
                        if job is self._job:
                            self._end_job(
                                ResultCode.PLANNING_FAILED,
                                started.describe(),
                                failure=started.failure,
                            )
                else:
                    runner = started
        self._robot = state  # one reference: arm() reads it from any thread
        with self._lock:
            self.states.now_s, self._safety = state.time_s, state.safety
            if job is not None and job is self._job and runner is not None:
                self._follow(job, runner)
            self._book.deliver()
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
                or self._recovery.active
                or job is None
                or job.runner is None
                or self.states.state is not S.EXECUTE
                or self._safety is not Safety.NORMAL
            ):
                return 0
            runner = job.runner
        n = runner.fast_forward(max_periods, until_s)
        if n:
            state = runner.ctx.last_state
            with self._lock:
                self.states.ticks += n
                self.states.now_s, self._safety = state.time_s, state.safety
                if job is self._job:
                    self._follow(job, runner)
                self._idle_transitions()
                self._publish()
        return n

    def _recovered(
        self, error: CellrunnerError | None, safety: Safety, failed: Event | None = None
    ) -> None:
        """A recovery ended (Clear's, ``failed`` its event when it fails; or Reset's unlock
        of a stop with no job): the robot's safety state, and why it failed."""
        with self._lock:
            if error is not None:
                self.log.info("clear_failed" if failed else "unlock_failed", error=str(error))
                if failed is not None:
                    self.states.on(failed)
            self._safety = safety

    def _follow(self, job: Job, runner: JobRunner) -> None:
        """Move the PackML state one step towards the runner's phase."""
        if job.runner is None:  # just started: Starting -> Execute
            job.runner = runner
            return self.states.job_started()
        if runner.done:
            assert runner.result is not None
            return self._end_job(runner.result, runner.message, runner)
        self.states.follow(runner.phase)

    def _idle_transitions(self) -> None:
        self.states.settle(self._safety, self._job is not None, self._recovery.active)

    def _end_job(
        self,
        code: ResultCode,
        message: str,
        runner: JobRunner | None = None,
        *,
        failure: Failure | None = None,
    ) -> None:
        """End the current job with ``code``: ``message`` its text, ``failure`` the
        planner's refusal behind it as data (a runner's own when None)."""
        job = self._job
        if job is None:
            return
        text = message or code.text
        self.last_runner = runner
        self._last_view = view_of(job, runner, code, text)
        self._job = None
        self.states.job_ended(code.is_fault)
        self.log.info("job_end", job_id=job.job_id, result_code=int(code), message=message)
        retries = runner.retries_used if runner else 0
        cycle = runner.cycle_time_s if runner else 0.0
        if failure is None and runner is not None:
            failure = runner.failure
        self._book.end(job, code, cycle, retries, text, failure)  # told once written (a full disk)
