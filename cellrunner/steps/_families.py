"""What the motion kinds share: a planned joint move, a straight TCP line, and a straight
line stopped by the wrist force each run the same way (:mod:`cellrunner.execution.steps`
streams an approved trajectory; :mod:`cellrunner.execution.force` guards a line)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.step_kinds import Motion, StepKindDef

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class MotionKind(StepKindDef):
    """A step that streams its approved trajectory."""

    motion: ClassVar[Motion | None] = "line"

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        from cellrunner.execution.steps import run_motion

        return run_motion(ctx, step, resume=resume)


class FrameLine(MotionKind):
    """A straight TCP line to a frame (``to``, ``offset``, ``pattern``), which may touch
    the fixtures named in ``contact``."""

    short_field = "to"
    short_schema = str
    short_types = (str,)

    def target(self, builder: Expansion, args: Any) -> tuple[str, np.ndarray | None, Any]:
        T, name = builder.target(args.to, args.offset, args.pattern)
        return name, T, None

    def target_frame(self, args: Any) -> str | None:
        return str(args.to)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.frame(spec.args.to, spec.path + ("to",))
        refs.contacts(spec.args, spec.path)

    def check_line(self, planner: Any, step: Step, path: np.ndarray) -> None:
        """A line into a tight fit slides along the fixtures named in ``contact:``; pressed
        into them (over a rim, an interference fit) it jams."""
        if not getattr(step.args, "contact", None):
            return
        from cellrunner.errors import InfeasibleError
        from cellrunner.planning.insert_fit import jam

        bare = planner.world.collision.carrying(planner.part)
        failure = jam(planner.world.kinematics, step, bare, path)
        if failure is not None:
            raise InfeasibleError(failure)


class RelativeLine(MotionKind):
    """A straight line of ``distance`` m from where the TCP stands."""

    short_field = "distance"

    def line_goal(self, planner: Any, step: Step, T_now: np.ndarray) -> np.ndarray:
        return self.relative_goal(step.args.distance, T_now)

    def relative_goal(self, distance_m: float, T_now: np.ndarray) -> np.ndarray:
        """T_world_tcp after ``distance_m`` of this line from ``T_now``."""
        raise NotImplementedError


class GuardedLine(MotionKind):
    """A straight line stopped by the wrist force (:mod:`cellrunner.execution.force`)."""

    motion: ClassVar[Motion | None] = "guarded"

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        from cellrunner.execution.force import run_force

        return run_force(ctx, step, resume=resume)


class ToolChangerStep(StepKindDef):
    """A lock or unlock of the tool changer: the planner mounts ``extra['tool']``."""

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.planning.task_plan import WRIST_SETTLE_S

        step = row.step
        planner.world = planner.world.with_tool(step.extra["tool"], tcp_of=step.extra["tcp_of"])
        row.world = planner.world
        row.duration_s = WRIST_SETTLE_S
