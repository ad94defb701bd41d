"""``descend``: a straight TCP line down to a frame (the second half of a pick or place)."""

from __future__ import annotations

from cellrunner.model.step_kinds import register
from cellrunner.model.task import LinearArgs
from cellrunner.steps._families import FrameLine


@register
class Descend(FrameLine):
    name = "descend"
    order = 2
    args = LinearArgs
    summary = "Straight TCP line to a frame (speed in m/s)."
    example = "infeed"
    colour = "#fc8d62"
