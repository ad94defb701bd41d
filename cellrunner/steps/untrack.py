"""``untrack``: let the belt go; the arm ramps back to where the tracked steps' plan
ends, at rest, so that the rest of the job runs as planned (SPEC section 13)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.base import Strict
from cellrunner.model.step_kinds import StepKindDef, register

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class UntrackArgs(Strict):
    """No arguments: it ends the track before it."""


@register
class Untrack(StepKindDef):
    name = "untrack"
    order = 15
    args = UntrackArgs
    bare = True
    top_level_only = True
    summary = "Stop following the belt: the arm ramps back to rest where the tracked steps end."
    example: ClassVar[Any] = {}
    colour = "#66c2a5"

    def expand(self, builder: Expansion, spec: Any, args: Any) -> None:
        step = builder.primitive(self.name, args, spec.path, builder.next_index())
        at = next(
            (i for i in range(len(builder.steps) - 1, -1, -1) if builder.steps[i].kind == "track"),
            None,
        )
        if at is not None:
            conveyor = builder.steps[at].args.conveyor
            step.extra["conveyor"] = conveyor
            for tracked in builder.steps[at + 1 :]:  # planned with room for the belt's motion
                tracked.extra["tracked"] = conveyor
        builder.steps.append(step)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        kinds = [s.kind for s in refs.task.steps]
        at = next(i for i, s in enumerate(refs.task.steps) if s is spec)
        before = kinds[:at]
        opened = len(before) - 1 - before[::-1].index("track") if "track" in before else None
        if opened is None or "untrack" in before[opened + 1 :]:
            refs.report.error(spec.path, "an untrack needs a track before it")

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.planning.belt_ramp import conveyor_ramp_s

        track = row.step.extra.get("conveyor")
        if track is None:
            return
        row.duration_s = conveyor_ramp_s(planner.world.loaded.cell.conveyors[track])

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    from cellrunner.execution.outcome import OK

    return OK
    yield  # a generator
