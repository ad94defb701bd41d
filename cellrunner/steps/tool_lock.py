"""``tool_lock``: a change_tool's lock of the tool changer on the tool in its rack (only
an expansion makes it); the planner mounts the tool."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model.step_kinds import register
from cellrunner.steps._families import ToolChangerStep

if TYPE_CHECKING:
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.step import Step


@register
class ToolLock(ToolChangerStep):
    name = "tool_lock"
    order = 30

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        from cellrunner.execution.tool_change import run_tool_lock

        return run_tool_lock(ctx, step)
