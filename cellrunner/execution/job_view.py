"""A job as the cell holds it (:class:`Job`) and as anyone reporting on it may see it:
the frozen :class:`JobView`, the PLC's :class:`~cellrunner.model.cellport.CellStatus`
snapshot, and the :class:`~cellrunner.model.cellport.JobResult` of a job that ended."""

from __future__ import annotations

from concurrent.futures import Future, wait
from dataclasses import dataclass, replace
from datetime import UTC, datetime

import numpy as np

from cellrunner.execution.job import JobRunner
from cellrunner.execution.job_records import JobPhase, StepRecord
from cellrunner.execution.journal import JobRecord
from cellrunner.execution.planner import PlannedJob
from cellrunner.model.cellport import CellStatus, JobResult
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step
from cellrunner.model.failure import Failure
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue
from cellrunner.model.robot_state import Safety
from cellrunner.model.trajectory import ApprovedTrajectory


@dataclass
class Job:
    """A job the cell accepted: planned on the worker (``plan``), then run (``runner``)."""

    job_id: str
    task: LoadedTask
    params: dict[str, ParamValue]
    client_job_id: str
    source: str
    plan: Future[PlannedJob] | None = None
    runner: JobRunner | None = None
    planned: PlannedJob | None = None

    def planned_motion_s(self, step: Step) -> float | None:
        """How long the approved trajectory of ``step`` lasts (s); None for a step
        without one, or before the plan is ready."""
        plan = self.plan
        if plan is None or not plan.done() or plan.exception():
            return None
        approved = plan.result().motions.nominal(step)
        return None if approved is None else approved.trajectory.duration_s

    def wait_for_plan(self, timeout_s: float) -> bool:
        """Block until the plan is ready or ``timeout_s`` passed; True when there is
        nothing to wait for (no plan asked for, or it was picked up already)."""
        if self.runner is not None or self.plan is None:
            return True
        done, _ = wait([self.plan], timeout=timeout_s)
        return bool(done)


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


def view_of(
    job: Job,
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


def obstruction_of(job: Job | None) -> str:
    """Where the running job's arm waits for an obstacle of the watched zone ("" when it
    does not)."""
    runner = job.runner if job is not None else None
    guard = runner.ctx.obstacles if runner is not None else None
    return guard.obstructed if guard is not None else ""


def streaming_of(job: Job | None) -> tuple[ApprovedTrajectory, int] | None:
    """The approved trajectory ``job`` streams now and the index of its next set-point."""
    runner = job.runner if job is not None else None
    stream = runner.ctx.stream if runner is not None else None
    return None if stream is None else (stream.approved, stream.next_index)


def status_of(
    state: S,
    job: Job | None,
    safety: Safety,
    last: JobResult | None,
    counters: tuple[int, int],
    *,
    held: bool = False,
    conveyor_speeds_mmps: tuple[tuple[str, int], ...] = (),
) -> CellStatus:
    """The PLC's snapshot of the cell: PackML ``state``, the ``job`` under way, the
    robot's ``safety``, the ``last`` result and the (processed, defective) ``counters``;
    ``held``: a job's result waits for the journal (a full disk), so the cell is busy."""
    obstruction = obstruction_of(job)
    holder = hold_of(job) if state in (S.HOLDING, S.HELD) else None
    if holder is None and obstruction:
        holder = HoldSource.OBSTACLE, f"{HoldSource.OBSTACLE.reason}: {obstruction}"
    return CellStatus(
        state=int(state),
        state_name=state.display_name,
        ready=state is S.IDLE and job is None and not held and safety is Safety.NORMAL,
        busy=job is not None or held,  # a result not yet journaled
        held=state in (S.HOLDING, S.HELD),
        protective_stop=safety is Safety.PROTECTIVE_STOP,
        estop=safety is Safety.EMERGENCY_STOP,
        job_id=job.job_id if job else "",
        step_index=job.runner.current_step if job and job.runner else 0,
        last_result=last,
        parts_processed=counters[0],
        parts_defective=counters[1],
        obstructed=bool(obstruction),
        obstruction=obstruction,
        hold_source=holder[0].value if holder else "",
        hold_reason=holder[1] if holder else "",
        conveyor_speeds_mmps=conveyor_speeds_mmps,
    )


def hold_of(job: Job | None) -> tuple[HoldSource, str] | None:
    """Who holds the running job and why (None: not held)."""
    runner = job.runner if job is not None else None
    hold = runner.hold if runner is not None else None
    if hold is None or hold.source is None:
        return None
    return hold.source, hold.reason


def result_of_job(
    job: Job,
    code: ResultCode,
    message: str,
    cycle_time_s: float,
    retries: int,
    failure: Failure | None = None,
) -> JobResult:
    """The result the PLC reads of ``job``, ended now with ``code`` (``failure``: the
    planner's refusal behind it, as data)."""
    return JobResult(
        job.job_id,
        code,
        message,
        cycle_time_s,
        datetime.now(UTC),
        retries,
        job.task.name,
        job.client_job_id,
        job.source,
        failure,
    )


def result_of_record(record: JobRecord) -> JobResult:
    """The result of a job the journal holds (the last one before a restart)."""
    end = datetime.fromtimestamp(record.ended_at, UTC) if record.ended_at else None
    return JobResult(
        record.job_id,
        ResultCode(record.result_code or 0),  # the journal's number, read back
        record.result_text or "",
        record.cycle_time_s or 0.0,
        end,
        record.retries,
        record.task,
        record.client_job_id or "",
        record.source,
        record.failure,
    )
