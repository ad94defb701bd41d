"""``set_output``: set outputs by their cell IO names, optionally as a pulse."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Strict
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.units import PositiveDuration

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlan, StepPlanner


class SetOutputArgs(Strict):
    """``{NAME: value}``: one or more outputs by their cell IO names."""

    model_config = Strict.model_config | {"extra": "allow"}

    pulse: PositiveDuration | None = None
    """Set the outputs, hold them this long (s), set them back. Example: `0.2`"""

    @model_validator(mode="after")
    def _values(self) -> SetOutputArgs:
        extra = self.model_extra or {}
        if not extra:
            raise PydanticCustomError("set_output", "set_output needs at least one {NAME: value}")
        for name, value in extra.items():
            if not isinstance(value, (bool, int, float)):
                raise PydanticCustomError(
                    "set_output",
                    f"output {name!r}: value must be true/false or a number, got {value!r}",
                )
        return self

    @property
    def values(self) -> dict[str, bool | float]:
        return dict(self.model_extra or {})


@register
class SetOutput(StepKindDef):
    name = "set_output"
    order = 8
    args = SetOutputArgs
    summary = "Set outputs by their cell IO names."
    example: ClassVar[Any] = {"beacon": True}
    colour = "#b3b3b3"

    def target(self, builder: Expansion, args: Any) -> tuple[str, None, None]:
        return ", ".join(f"{k}={v}" for k, v in args.values.items()), None, None

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        for name in spec.args.values:
            refs.output(name, spec.path + (name,))

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        row.duration_s = (row.step.args.pulse or 0.0) + 1.0 / planner.world.spec.rate_hz

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        return _run(ctx, step)


def _run(ctx: JobContext, step: Step) -> StepGen:
    """Set the outputs; with ``pulse``, hold them that long and set them back (false, 0)."""
    from cellrunner.execution.outcome import OK

    values = step.args.values
    for name, value in values.items():
        ctx.backend.set_output(ctx.outputs[name], value)
    yield
    pulse_s = step.args.pulse
    if pulse_s:
        t0 = ctx.now_s
        while ctx.now_s - t0 < pulse_s - 1e-9:
            yield
        for name, value in values.items():
            ctx.backend.set_output(ctx.outputs[name], False if isinstance(value, bool) else 0.0)
        yield
    return OK
