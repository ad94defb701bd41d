"""``wait``: stand still for a time."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any

from pydantic import Field

from cellrunner.model.base import Strict
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.units import Duration

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.expand import Expansion
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class WaitArgs(Strict):
    seconds: Annotated[Duration, Field(le=3600)]
    """Time to wait, s (or a string with a unit). Example: `0.5`"""


@register
class Wait(StepKindDef):
    name = "wait"
    order = 10
    args = WaitArgs
    summary = "Wait this long, s."
    example = 0.5
    short_field = "seconds"
    short_schema = float
    colour = "#cccccc"

    def target(self, builder: Expansion, args: Any) -> tuple[str, None, None]:
        return f"{args.seconds:g} s", None, None

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        row.duration_s = row.step.args.seconds

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    from cellrunner.execution.context import Hold
    from cellrunner.execution.outcome import OK

    t0 = ctx.now_s
    while ctx.now_s - t0 < step.args.seconds:
        ctx.hold = Hold(t0, until_s=step.args.seconds)
        yield
    return OK
