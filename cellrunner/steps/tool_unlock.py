"""``tool_unlock``: a change_tool's release of the mounted tool into its rack (only an
expansion makes it); the planner plans on with the bare flange."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model.step_kinds import register
from cellrunner.steps._families import ToolChangerStep

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.step import Step


@register
class ToolUnlock(ToolChangerStep):
    name = "tool_unlock"
    order = 31

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        from cellrunner.execution.tool_change import run_tool_unlock

        return run_tool_unlock(ctx, step)
