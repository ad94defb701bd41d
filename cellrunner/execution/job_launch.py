"""From an accepted job to a running one: its plan made on a worker thread (so that no
control tick waits for planning), then its runner built with the job's context and
started on the control thread."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.backends.base import RobotBackend
from cellrunner.errors import CellrunnerError, InfeasibleError
from cellrunner.execution.belt_watch import BeltWatch
from cellrunner.execution.context import QUIET, EventLog, Eye, JobContext, Motions, use_gripper
from cellrunner.execution.job import JobRunner
from cellrunner.execution.job_book import JobBook
from cellrunner.execution.job_view import Job
from cellrunner.execution.planner import PlannedJob, Planner
from cellrunner.execution.plc_encoders import PlcEncoders, Registers, has_plc_encoders
from cellrunner.model.expand import Step
from cellrunner.model.failure import Failure
from cellrunner.model.gripper import gripper_channels
from cellrunner.model.load import LoadedCell
from cellrunner.model.robot_state import RobotState
from cellrunner.model.timing import release_time_s

if TYPE_CHECKING:
    from cellrunner.backends.base import MeasuresConveyors


@dataclass(frozen=True)
class PlanRefused:
    """A job's plan could not be made (the job ends with 103): ``error`` as the planner
    raised it (an :class:`~cellrunner.errors.InfeasibleError` naming the step and its
    blockers, or a planner bug)."""

    error: Exception

    @property
    def failure(self) -> Failure | None:
        """The planner's refusal as data (None for a planner bug)."""
        return self.error.failure if isinstance(self.error, InfeasibleError) else None

    def describe(self) -> str:
        """The job's message: the error's text; a bug's also names its type."""
        exc = self.error
        return str(exc) if isinstance(exc, CellrunnerError) else f"{type(exc).__name__}: {exc}"


class JobLauncher:
    """Plans a cell's jobs (one at a time, on its own thread) and starts their runners."""

    def __init__(
        self,
        cell: LoadedCell,
        backend: RobotBackend,
        book: JobBook,
        planner: Planner,
        *,
        log: EventLog | None = None,
        wait_for_unhold: bool = True,
        on_step_start: Callable[[Step, int], None] | None = None,
        gate: Callable[[Step], bool] | None = None,
        eye: Eye | None = None,
        watch: Any = None,
    ) -> None:
        self.cell, self.backend, self.book, self.planner = cell, backend, book, planner
        self.log, self.wait_for_unhold = log, wait_for_unhold
        self.on_step_start = on_step_start
        self.gate = gate  # run --step: each step starts once gate(step) is true
        self.eye = eye  # the cameras, for align steps
        self._belts: BeltWatch | None = None
        #: the PLC server's registers, where ``serve`` has a Modbus server: the encoders of
        #: the cell's ``source: plc`` belts (:mod:`.plc_encoders`)
        self._plc_registers: Callable[[], Registers] | None = None
        #: the watched zone (execution.watch.ZoneWatch) whose map every motion is checked
        #: against (SPEC 12); None: the cell is not watched
        self.watch = watch
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")

    def plan(self, job: Job, q_now_rad: np.ndarray) -> None:
        """Start planning ``job`` from where the arm stands (its plan: ``job.plan``)."""
        job.plan = self._pool.submit(self.planner, job.task, job.params, q_now_rad)

    def start(self, job: Job) -> JobRunner | PlanRefused:
        """The runner of ``job`` following its plan, started (it reads the robot); why
        planning failed instead, when it did (the job ends with 103)."""
        assert job.plan is not None and job.plan.done()  # called once the plan is ready
        try:
            plan: PlannedJob = job.plan.result()
        except Exception as exc:  # a planner bug must still close the job with a code
            return PlanRefused(exc)
        job.planned = plan
        ctx = self._context(plan.motions, job.job_id)
        if self.watch is not None:
            from cellrunner.execution.obstacles import ObstacleGuard

            ctx.obstacles = ObstacleGuard(
                self.watch,
                job.task.task.on_obstacle,
                self.watch.world.limits.joint_accel_rad_s2,
            )
            self.backend.job_started()  # the twin's intruders count from the job's start
        runner = JobRunner(
            ctx,
            plan.run_steps,
            job.task.task.on_protective_stop,
            wait_for_unhold=self.wait_for_unhold,
            gate=self.gate,
            on_step=lambda rec, attempt: self.book.step(job, rec, attempt),
        )
        runner.start()
        return runner

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)

    def read_plc_encoders(self, registers: Callable[[], Registers]) -> None:
        """Measure the cell's ``source: plc`` belts from now on from ``registers()`` (the
        PLC server's, read every period), the others from the backend as before."""
        self._plc_registers = registers
        if self._belts is not None:
            measure = self._measure()
            if measure is not None:
                self._belts.backend = measure

    def _measure(self) -> MeasuresConveyors | PlcEncoders | None:
        """What measures the cell's belts: the backend, and the PLC's registers for the
        belts the PLC counts once they are there; None when nothing does."""
        from cellrunner.backends.base import MeasuresConveyors

        c = self.cell.cell
        backend = self.backend if isinstance(self.backend, MeasuresConveyors) else None
        registers = self._plc_registers
        if registers is not None and has_plc_encoders(c.conveyors):
            return PlcEncoders(c.conveyors, registers, backend, self.log or QUIET)
        return backend

    def _belt_watch(self) -> BeltWatch | None:
        """The conveyors' watch, kept from job to job (parts latched between them stay),
        when the cell has conveyors the backend (or the PLC) measures."""
        c = self.cell.cell
        if not c.conveyors:
            return None
        if self._belts is None:
            measure = self._measure()
            if measure is None:
                return None
            self._belts = BeltWatch(measure, dict(c.conveyors), dict(c.io.inputs))
        return self._belts

    def note_belts(self, state: RobotState) -> None:
        """Between jobs: the conveyors' encoders and eyes of this period."""
        belts = self._belt_watch()
        if belts is not None:
            belts.note(state)

    def conveyor_speeds_mmps(self) -> tuple[tuple[str, int], ...]:
        """Each measured conveyor's speed, mm/s (rounded), for the PLC."""
        belts = self._belts
        if belts is None:
            return ()
        out = []
        for name, view in belts.belts.items():
            speed = view.speed_mps()
            if speed is not None:
                out.append((name, round(speed * 1000)))
        return tuple(out)

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
            belts=self._belt_watch(),
        )
        use_gripper(ctx, g)
        return ctx
