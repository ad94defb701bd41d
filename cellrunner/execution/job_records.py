"""What a job's runner keeps of its steps: its phase (:class:`JobPhase`), one row per
expanded step (:class:`StepRecord`, what the report and the journal show), and the items
on its agenda (:class:`AgendaItem`: a step with its attempt and how it is run)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from cellrunner.model.expand import Step


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
class AgendaItem:
    """A step on the runner's agenda: run as itself, weighed, or waited out still."""

    step: Step
    attempt: int = 1
    behaviour: str = "step"  # step | weigh | still
    resume: bool = False
    gated: bool = False  # the gate (run --step) let it start
    between: bool = False  # a retry's in-between step (not a row of its own)

    def timeout_s(self, motion_timeout_s: float) -> float:
        """How long the item may take (s): a motion the cell's ``step_timeout``, any other
        step its own timeout (or wait, or pulse) and 5 s."""
        step = self.step
        if step.is_motion:
            return motion_timeout_s
        timeout = (
            getattr(step.args, "timeout", None)
            or getattr(step.args, "seconds", 0.0)
            or getattr(step.args, "pulse", 0.0)
            or 0.0
        )
        return float(timeout) + 5.0
