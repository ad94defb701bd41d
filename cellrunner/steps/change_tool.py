"""``change_tool``: park the mounted tool in its rack, take the named tool, switch TCP,
payload and collision geometry (expanded by :mod:`cellrunner.model.tool_change`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cellrunner.model.diagnose import unknown_name
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.tool_steps import ChangeToolArgs

if TYPE_CHECKING:
    from cellrunner.model.expand import Expansion
    from cellrunner.model.loaded import StepSpec
    from cellrunner.model.references import ReferenceCheck


@register
class ChangeTool(StepKindDef):
    name = "change_tool"
    order = 15
    args = ChangeToolArgs
    macro = True
    top_level_only = True
    summary = (
        "Macro: park the mounted tool in its rack, take the named tool, switch TCP, "
        "payload and collision geometry."
    )
    example = "cup"
    short_field = "tool"
    short_schema = str
    short_types = (str,)

    def expand(self, builder: Expansion, spec: StepSpec, args: Any) -> None:
        from cellrunner.model.tool_change import expand_change_tool

        steps, builder.tool = expand_change_tool(
            builder.cell, spec, builder.tool, builder.next_index()
        )
        builder.steps.extend(steps)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        cell, tool, path, report = refs.cell, spec.args.tool, spec.path, refs.report
        if tool not in cell.tools:
            known = list(cell.tools)
            report.error(
                path + ("tool",) if not refs.is_short(path) else path,
                unknown_name("tool", tool, known)
                if known
                else f"unknown tool {tool!r}: the cell has no 'tools:' to change between",
            )
        elif cell.tool_changer is None:
            report.error(
                path,
                f"change_tool needs the cell's tool_changer: {{lock: OUTPUT, locked: INPUT, "
                f"rack: {{NAME: FRAME}}}}; cell {cell.cell!r} has none",
            )
