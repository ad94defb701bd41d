"""What a :class:`~cellrunner.execution.cell.CellController` shows without changing
anything: the arm as last measured, the job under way and the last one, the task menu.
Read-only queries, kept apart from the controller's state changes."""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

from cellrunner.execution.context import Eye
from cellrunner.execution.job_view import JobView, obstruction_of, status_of, streaming_of, view_of
from cellrunner.model.cellport import ArmStatus, CellStatus, JobResult
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.robot_state import Safety

if TYPE_CHECKING:
    from cellrunner.backends.base import RobotBackend
    from cellrunner.execution.cell_states import CellStates
    from cellrunner.execution.job_book import JobBook
    from cellrunner.execution.job_launch import JobLauncher
    from cellrunner.execution.job_view import Job
    from cellrunner.execution.planner import PlannedJob
    from cellrunner.execution.task_menu import TaskMenu
    from cellrunner.model.expand import Step
    from cellrunner.model.load import LoadedCell, LoadedTask
    from cellrunner.model.robot_state import RobotState
    from cellrunner.model.trajectory import ApprovedTrajectory


class CellViews:
    """The read-only half of the cell controller (a mixin over its state)."""

    cell: LoadedCell
    tasks: dict[int, LoadedTask]
    backend: RobotBackend
    states: CellStates
    _menu: TaskMenu
    _launcher: JobLauncher
    _job: Job | None
    _last_view: JobView | None
    _robot: RobotState | None
    _status: CellStatus
    _safety: Safety
    _book: JobBook
    _lock: threading.RLock

    def held_results(self) -> list[str]:
        """The results the journal has not written yet (a full disk), for SIGTERM's report."""
        return self._book.held()

    def _status_inputs(self) -> tuple[object, ...]:
        """Everything the status snapshot shows: a new one is made when this changed."""
        job = self._job
        return (
            self.states.state,
            job,
            self._book.holding,
            self._safety,
            job.runner.current_step if job and job.runner else 0,
            self._book.last,
            self._book.counters,
            obstruction_of(job),
            self._launcher.conveyor_speeds_mmps(),
        )

    def status(self) -> CellStatus:
        """The snapshot published after the last change; takes no lock, never waits."""
        return self._status

    def finished_job(self, source: str, client_job_id: str) -> JobResult | None:
        """The journal's result of the job ``source`` named ``client_job_id`` (a
        :class:`~cellrunner.model.cellport.JobHistory`); None when it has not ended."""
        with self._lock:
            return self._book.finished(source, client_job_id)

    def _snapshot(self) -> CellStatus:
        return status_of(
            self.states.state,
            self._job,
            self._safety,
            self._book.last,
            self._book.counters,
            held=self._book.holding,
            conveyor_speeds_mmps=self._launcher.conveyor_speeds_mmps(),
        )

    def arm(self) -> ArmStatus:
        """The arm as the last tick measured it (:class:`~cellrunner.model.cellport.ArmPort`);
        takes no lock, never touches the backend."""
        robot, job = self._robot, self._job
        return ArmStatus(
            model=self.cell.cell.robot.model,
            serial_number=str(getattr(self.backend, "serial_number", "") or ""),
            controller=str(getattr(self.backend, "robot_model", "") or ""),
            q_rad=() if robot is None else tuple(float(q) for q in robot.q_rad),
            qd_rad_s=() if robot is None else tuple(float(v) for v in robot.qd_rad_s),
            emergency_stop=robot is not None and robot.safety is Safety.EMERGENCY_STOP,
            protective_stop=robot is not None and robot.safety is Safety.PROTECTIVE_STOP,
            task=job.task.name if job is not None else "",
            time_s=0.0 if robot is None else robot.time_s,
        )

    # ------------------------------------------------------------------ job views
    @property
    def busy(self) -> bool:
        """A job is under way or its end is still being shown (Starting, Completing,
        Aborting): a loop running one job ticks on while this is true."""
        return self._job is not None or self.states.state in (S.COMPLETING, S.ABORTING, S.STARTING)

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
        return None if job is None else view_of(job, job.runner, records=records)

    def streaming(self) -> tuple[ApprovedTrajectory, int] | None:
        """The approved trajectory the running job streams now and the index of its next
        set-point, or None (call on the control thread)."""
        return streaming_of(self._job)

    def planned_job(self) -> PlannedJob | None:
        """The running job's plan once it is ready (None before, and with no job): a
        frozen object that any thread may read (the status page draws its path)."""
        job = self._job
        return None if job is None else job.planned

    @property
    def eye(self) -> Eye | None:
        """The cameras align steps look through (None: the cell has none)."""
        return self._launcher.eye

    @property
    def last_job(self) -> JobView | None:
        """The last job that ended, as it ended (its step records, result and tracking)."""
        return self._last_view

    def planned_motion_s(self, step: Step) -> float | None:
        """How long the running job's approved trajectory of ``step`` lasts (s); None for
        a step without one, or before the plan is ready."""
        job = self._job
        return None if job is None else job.planned_motion_s(step)

    def wait_for_plan(self, timeout_s: float) -> bool:
        """Block (not the control loop's business while a job plans) until the running
        job's plan is ready or ``timeout_s`` passed; True when there is nothing to wait for."""
        job = self._job
        return job is None or job.wait_for_plan(timeout_s)

    def task_params(self, task: str | int) -> list[str] | None:
        return self._menu.param_names(task)

    def task_names(self) -> list[str]:
        """The tasks' names in PLC task number order (a TaskCatalog)."""
        return [loaded.name for _, loaded in sorted(self.tasks.items())]

    def task_param_specs(self, task: str | int) -> list[tuple[str, str, str | None]] | None:
        return self._menu.param_specs(task)
