"""What a job's runner keeps of its steps: its phase (:class:`JobPhase`), one row per
expanded step (:class:`StepRecord`, what the report and the journal show), and the items
on its agenda (:class:`AgendaItem`: a step with its attempt and how it is run)."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from cellrunner.model.expand import Step

if TYPE_CHECKING:
    from cellrunner.execution.obstacle_guard import ObstacleGuard


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
    HELD = "held"  # a journal row only: the job was held in this step (who, in its message)


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


class StepRows:
    """A job's rows, one per expanded step (``records``, by step index), each handed to
    ``on_step`` (the journal) with the attempt as it changes; a row that ended says what
    the watched zone's ``obstacles`` did to its step."""

    def __init__(
        self,
        steps: list[Step],
        on_step: Callable[[StepRecord, int], None] | None,
        obstacles: ObstacleGuard | None,
    ) -> None:
        self.records: dict[int, StepRecord] = {}
        self.on_step, self.obstacles = on_step, obstacles
        self.add(steps)

    def add(self, steps: list[Step]) -> None:
        for s in steps:
            self.records[s.index] = StepRecord(s.index, s.kind, s.name)

    def started(self, index: int, attempt: int, now_s: float) -> None:
        record = self.records[index]
        record.status, record.attempts = StepStatus.RUNNING, max(record.attempts, attempt)
        if record.started_s is None:
            record.started_s = now_s
        self._journal(record, attempt)

    def ok(self, index: int, attempt: int, now_s: float, message: str) -> None:
        """The step went through; ``message`` says what it measured (an align), if anything."""
        record = self.records[index]
        record.status, record.message = StepStatus.OK, message or record.message
        assert record.started_s is not None  # set when the step started
        record.duration_s = now_s - record.started_s
        self._journal(record, attempt)

    def failed(self, index: int, attempt: int, now_s: float, message: str) -> None:
        record = self.records[index]
        record.status, record.message = StepStatus.FAILED, message
        record.duration_s = now_s - (record.started_s or now_s)
        self._journal(record, attempt)

    def fail_running(self, index: int, attempt: int, now_s: float, message: str) -> None:
        """Step ``index`` failed with ``message`` if it is running."""
        if self.records[index].status is StepStatus.RUNNING:
            self.failed(index, attempt, now_s, message)

    def held(self, index: int, attempt: int, message: str) -> None:
        """The job was held in step ``index``: one journal row (status ``held``) whose
        ``message`` says who held and why; the step's own row goes on as it was."""
        if self.on_step is not None:
            record = self.records[index]
            self.on_step(replace(record, status=StepStatus.HELD, message=message), attempt)

    def skip_pending(self) -> None:
        for record in self.records.values():
            if record.status is StepStatus.PENDING:
                record.status = StepStatus.SKIPPED

    def _journal(self, record: StepRecord, attempt: int) -> None:
        if self.obstacles is not None and record.status is not StepStatus.RUNNING:
            met = self.obstacles.summary(record.index)
            if met and met not in record.message:
                record.message = f"{record.message}; {met}" if record.message else met
        if self.on_step is not None:
            self.on_step(record, attempt)


@dataclass
class AgendaItem:
    """A step on the runner's agenda: run as itself, weighed, or waited out still."""

    step: Step
    attempt: int = 1
    behaviour: str = "step"  # step | weigh | still
    resume: bool = False
    gated: bool = False  # the gate (run --step) let it start
    between: bool = False  # a retry's in-between step (not a row of its own)

    def timeout_s(self, motion_timeout_s: float) -> float:
        """How long the item may take (s): a motion, or a ``track`` (it waits for a part
        and runs its tracked stretch), the cell's ``step_timeout``; any other step its own
        timeout (or wait, or pulse) and 5 s."""
        step = self.step
        if step.is_motion or step.kind == "track":
            return motion_timeout_s
        timeout = (
            getattr(step.args, "timeout", None)
            or getattr(step.args, "seconds", 0.0)
            or getattr(step.args, "pulse", 0.0)
            or 0.0
        )
        return float(timeout) + 5.0
