"""``release``: open the jaws (or break the vacuum), optionally confirmed by an input; a
place's release is where the twin judges the part against the place's target."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.task import GripArgs

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


@register
class Release(StepKindDef):
    name = "release"
    order = 7
    args = GripArgs
    bare = True
    summary = "Open the jaws (optionally confirmed by an input)."
    example: ClassVar[Any] = {"timeout": 1.0}
    colour = "#ffd92f"

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.needs_gripper = True
        if spec.args.confirm is not None:
            refs.input(spec.args.confirm, spec.path + ("confirm",))

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.model.timing import release_time_s

        step = row.step
        # a place's release: where the twin judges the part against the place's target
        # (a bare release, after an insert or in on_error, is judged by its confirm input)
        part = planner.part
        if part is not None and step.macro_kind == "place":
            from cellrunner.planning.support import check_support

            check_support(planner.world, step, planner.q, part, step.extra.get("earlier_slots", []))
        row.duration_s = release_time_s(planner.world.loaded.cell.tool.gripper)
        if part is not None:
            # it rests where it was let go (a place's: check_support), or, let go by a bare
            # release (after an insert: in its hole), no higher than that: an obstacle to
            # every later step either way (the open jaws of the move home once swept through
            # the top of a pin standing in its hole: issue 33, s3000)
            from cellrunner.planning.placed import placed_part

            T_world_part = planner.world.kinematics.T_world_tcp(planner.q) @ part.T_parent_shape
            planner.world = planner.world.with_placed(
                placed_part(part, T_world_part, str(step.index))
            )
        planner.part = None

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    """Open the jaws; with a confirmation input, wait for it (or the closed sensor) to drop."""
    from cellrunner.execution.context import Hold
    from cellrunner.execution.outcome import Outcome
    from cellrunner.execution.steps import check_place
    from cellrunner.model.codes import ResultCode

    args = step.args
    if ctx.gripper_open is not None:
        channel, value = ctx.gripper_open
        ctx.backend.set_output(channel, value)
    if ctx.gripper_close is not None:
        channel, value = ctx.gripper_close
        ctx.backend.set_output(channel, (not value) if isinstance(value, bool) else 0.0)
    ctx.carry = None
    t0 = ctx.now_s
    if ctx.gripper_blow_off is not None:  # a vacuum gripper's blow-off pulse breaks the seal
        channel, pulse_s = ctx.gripper_blow_off
        ctx.backend.set_output(channel, True)
        while ctx.now_s - t0 < pulse_s:
            yield
        ctx.backend.set_output(channel, False)
    confirm = ctx.inputs.get(args.confirm) if args.confirm else None
    watch = confirm or ctx.gripper_closed_sensor
    while ctx.now_s - t0 < ctx.gripper_open_s or (
        watch and _release_pending(ctx, watch, confirm is not None)
    ):
        if ctx.now_s - t0 >= args.timeout:
            if confirm is not None:
                return Outcome.failed(
                    ResultCode.PLACE_FAILED,
                    f"place failed: {args.confirm} not true within "
                    f"{args.timeout:g} s after the release",
                )
            return Outcome.failed(
                ResultCode.PLACE_FAILED, f"release not confirmed within {args.timeout:g} s"
            )
        # the inputs read the same until the look-ahead stops: only the time can end it
        pending = bool(watch and _release_pending(ctx, watch, confirm is not None))
        until_s = math.inf if pending else ctx.gripper_open_s
        ctx.hold = Hold(t0, until_s=until_s, timeout_s=args.timeout)
        yield
    return (yield from check_place(ctx, step))


def _release_pending(ctx: JobContext, channel: str, is_open_confirm: bool) -> bool:
    value = bool(ctx.last_state.inputs.get(channel))
    return not value if is_open_confirm else value
