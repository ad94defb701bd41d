"""``wait_input``: wait until an input reads a value, failing after a timeout (105)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.base import Name, Strict
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.units import PositiveDuration

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class WaitInputArgs(Strict):
    input: Name
    """Input name from io.inputs. Example: `part_present`"""
    value: bool | float = True
    """Value to wait for. Example: `true`"""
    timeout: PositiveDuration = 10.0
    """Seconds before the step fails with 105. Example: `10`"""


@register
class WaitInput(StepKindDef):
    name = "wait_input"
    order = 9
    args = WaitInputArgs
    summary = "Wait until an input reads `value`, failing the step after `timeout` (s)."
    example: ClassVar[Any] = {"input": "part_present", "value": True, "timeout": 10}
    colour = "#cccccc"

    def target(self, builder: Expansion, args: Any) -> tuple[str, None, None]:
        return str(args.input), None, None

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.input(spec.args.input, spec.path + ("input",))

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        args = row.step.args
        row.message = f"waits up to {args.timeout:g} s for {args.input}"

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    from cellrunner.execution.context import Hold
    from cellrunner.execution.outcome import OK, Outcome
    from cellrunner.model.codes import ResultCode

    args = step.args
    channel = ctx.inputs[args.input]
    t0 = ctx.now_s
    while ctx.last_state.inputs.get(channel) != args.value and not (
        isinstance(args.value, bool) and bool(ctx.last_state.inputs.get(channel)) == args.value
    ):
        if ctx.now_s - t0 >= args.timeout:
            return Outcome.failed(
                ResultCode.STEP_TIMEOUT,
                f"input {args.input} did not read {args.value} within {args.timeout:g} s",
            )
        ctx.hold = Hold(t0, timeout_s=args.timeout)
        yield
    return OK
