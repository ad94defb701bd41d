"""``track``: start following the oldest part the conveyor's photo-eye latched (SPEC
section 13). Until ``untrack``, the steps are planned for the part standing still at the
conveyor's frame and run with the belt's offset added (:mod:`cellrunner.planning.tracking`
proves them; :mod:`cellrunner.planning.belt_ramp` takes up the belt's motion)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.base import Name, Strict
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.step_kinds import StepKindDef, kind_of, register

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class TrackArgs(Strict):
    conveyor: Name
    """The conveyor (from the cell's conveyors) whose oldest latched part the arm follows. Example: `belt`"""


@register
class Track(StepKindDef):
    name = "track"
    order = 14
    args = TrackArgs
    top_level_only = True
    summary = "Follow the oldest part the conveyor latched: until untrack, targets on the belt move with it."
    example: ClassVar[Any] = {"conveyor": "belt"}
    short_field = "conveyor"
    short_types = (str,)
    short_schema = str
    colour = "#66c2a5"

    def target(self, builder: Any, args: Any) -> tuple[str, None, None]:
        return str(args.conveyor), None, None

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        conveyors = refs.cell.conveyors
        if spec.args.conveyor not in conveyors:
            refs.report.error(
                spec.path + ("conveyor",), unknown_name("conveyor", spec.args.conveyor, conveyors)
            )
        kinds = [s.kind for s in refs.task.steps]
        at = next(i for i, s in enumerate(refs.task.steps) if s is spec)
        after = kinds[at + 1 :]
        closing = after.index("untrack") if "untrack" in after else None
        if closing is None:
            refs.report.error(
                spec.path, "a track needs an untrack after it (where the arm lets the belt go)"
            )
        elif "track" in after[:closing]:
            refs.report.error(
                spec.path, "a track before the untrack of the one before it: untrack first"
            )
        elif spec.args.conveyor in conveyors:
            tracked = refs.task.steps[at + 1 : at + 1 + closing]
            _check_on_belt(refs, conveyors[spec.args.conveyor].frame, tracked)

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.planning.belt_ramp import conveyor_ramp_s

        row.duration_s = conveyor_ramp_s(
            planner.world.loaded.cell.conveyors[row.step.args.conveyor]
        )

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _check_on_belt(refs: ReferenceCheck, belt_frame: str, tracked: list[Any]) -> None:
    """While tracking, every target moves with the belt: a step aimed at a frame that is
    not the conveyor's (or one given in it), or a joint move, is refused."""
    frames = refs.cell.frames
    on_belt = {belt_frame}
    for _ in range(len(frames)):  # frames given in a frame on the belt ride it too
        on_belt |= {name for name, f in frames.items() if f.parent in on_belt}
    for spec in tracked:
        kind = kind_of(spec.kind)
        frame = kind.target_frame(spec.args)
        if frame is not None and frame in frames and frame not in on_belt:
            refs.report.error(
                spec.path,
                f"between track and untrack every target moves with the belt; {frame!r} is "
                f"not on it (frames on it: {', '.join(sorted(on_belt))}); untrack first",
            )
        elif frame is None and kind.motion == "planned":
            refs.report.error(
                spec.path,
                "between track and untrack every target moves with the belt; a joint target "
                "does not: untrack first",
            )


def _run(ctx: JobContext, step: Step) -> StepGen:
    from cellrunner.execution.belt_tracking import run_track

    return run_track(ctx, step)
