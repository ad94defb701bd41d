"""A grip's retry policy (the task's ``retry:``): a grip that finds no part is tried
again, up to ``attempts`` times, after its ``between`` steps and from ``redo_from``;
a grip with a force window weighs its part after the lift that follows it."""

from __future__ import annotations

from cellrunner.execution.job_records import AgendaItem, StepRecord, StepStatus
from cellrunner.model.expand import Step
from cellrunner.model.step import StepKind


def grip_of(item: AgendaItem) -> Step | None:
    """The grip step an item's NO_PART failure belongs to (the grip itself or its weighing)."""
    return item.step if item.step.kind == StepKind.GRIP and not item.between else None


def retry_agenda(
    steps: list[Step], records: dict[int, StepRecord], grip: Step, attempt: int
) -> list[AgendaItem]:
    """What runs for attempt ``attempt`` of ``grip``: its ``between`` steps, the steps from
    ``redo_from`` to the grip, then every step after it not yet done (a failed weighing
    also redoes its lift)."""
    retry = grip.retry
    assert retry is not None  # only a grip with a retry is retried
    redo = [s for s in steps if retry.redo_from <= s.index <= grip.index]
    rest = [
        AgendaItem(s, attempt)
        for s in steps
        if s.index > grip.index
        and (records[s.index].status is StepStatus.PENDING or s.index == grip.index + 1)
    ]
    return (
        [AgendaItem(b, attempt, between=True) for b in retry.between]
        + [AgendaItem(s, attempt) for s in redo]
        + rest
    )


def weighing_after(steps: list[Step], item: AgendaItem) -> AgendaItem | None:
    """A lift right after a grip with a force window: the weighing of the part, to run
    next (None: nothing to weigh)."""
    step = item.step
    if step.kind != StepKind.LIFT or item.behaviour != "step" or item.between:
        return None
    grip = next((s for s in steps if s.index == step.index - 1), None)
    if grip is not None and grip.kind == "grip" and grip.args.force is not None:
        return AgendaItem(grip, item.attempt, behaviour="weigh")
    return None
