"""``grip``: close the jaws (or the vacuum), then check the confirmation input and the
measured force window."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.task import GripArgs

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


@register
class Grip(StepKindDef):
    name = "grip"
    order = 6
    args = GripArgs
    bare = True
    summary = "Close the jaws, then check the confirmation input and the measured force window."
    example: ClassVar[Any] = {
        "confirm": "gripper_closed",
        "force": {"min": 2, "max": 40},
        "timeout": 1.5,
    }
    colour = "#a6d854"

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.needs_gripper = True
        if spec.args.confirm is not None:
            refs.input(spec.args.confirm, spec.path + ("confirm",))

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.model.timing import close_time_s
        from cellrunner.planning.task_plan import WRIST_SETTLE_S, check_jaws_fit

        step, world = row.step, planner.world
        gripper = world.loaded.cell.tool.gripper
        T = world.kinematics.T_world_tcp(planner.q)
        # a pick's grip names its frame; a bare grip takes the part waiting at the TCP
        frame = step.extra.get("part_at") or planner.frame_at_tcp()
        part = world.part_at(frame, T, step.extra.get("part_pose"))
        planner.part = world.same_grip(part) if part is not None else None
        check_jaws_fit(step, gripper, planner.part)
        weigh = WRIST_SETTLE_S if step.args.force is not None else 0.0
        close_s = close_time_s(gripper, planner.part.shape if planner.part is not None else None)
        row.duration_s = WRIST_SETTLE_S + close_s + weigh

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    """Close the jaws; succeed when the confirmation input reads true within the timeout."""
    import numpy as np

    from cellrunner.execution.context import Carry, Hold
    from cellrunner.execution.outcome import OK, Outcome
    from cellrunner.execution.steps import AVERAGE_S, SETTLE_S
    from cellrunner.model.codes import ResultCode

    args = step.args
    if ctx.gripper_close is None:
        return Outcome.failed(ResultCode.NO_PART, "the cell has no gripper close output")
    samples: list[np.ndarray] = []
    t0 = ctx.now_s
    while ctx.now_s - t0 < SETTLE_S + AVERAGE_S:  # settle, then the baseline
        if ctx.now_s - t0 >= SETTLE_S:
            samples.append(np.array(ctx.last_state.wrench_N[:3], dtype=float))
        ctx.hold = Hold(t0, until_s=SETTLE_S + AVERAGE_S, sample_from_s=SETTLE_S, samples=samples)
        yield
    baseline = (
        np.mean(samples, axis=0) if samples else np.array(ctx.last_state.wrench_N[:3], dtype=float)
    )
    channel, value = ctx.gripper_close
    ctx.backend.set_output(channel, value)
    confirm = ctx.inputs.get(args.confirm) if args.confirm else ctx.gripper_closed_sensor
    t0 = ctx.now_s
    if confirm is None:  # no sensor: all we can do is let the jaws travel
        while ctx.now_s - t0 < min(args.timeout, 0.5):
            ctx.hold = Hold(t0, until_s=min(args.timeout, 0.5))
            yield
    else:
        while not ctx.last_state.inputs.get(confirm):
            if ctx.now_s - t0 >= args.timeout:
                return Outcome.failed(
                    ResultCode.NO_PART,
                    f"{args.confirm or 'closed sensor'} not true "
                    f"within {args.timeout:g} s ({_gripped_nothing(ctx)})",
                )
            ctx.hold = Hold(t0, timeout_s=args.timeout)
            yield
    force_min = args.force.min if args.force else 0.0
    ctx.notes.pop("sensor_false_since", None)
    ctx.notes.pop("load_lp", None)
    ctx.carry = Carry(
        baseline_N=baseline, min_N=force_min, confirm=confirm, tool_mass_kg=ctx.tool_mass_kg
    )
    return OK


def _gripped_nothing(ctx: JobContext) -> str:
    return (
        "no vacuum: the cups sealed on nothing"
        if ctx.gripper_kind == "vacuum"
        else "jaws closed on nothing"
    )
