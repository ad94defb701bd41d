"""Arguments of ``change_tool`` (expanded by :mod:`cellrunner.model.tool_change`)."""

from __future__ import annotations

from cellrunner.model.base import Name, Strict


class ChangeToolArgs(Strict):
    """``change_tool: NAME``: park the mounted tool in its rack place, take tool ``tool``."""

    tool: Name
    """The tool to take. Example: `cup`"""
