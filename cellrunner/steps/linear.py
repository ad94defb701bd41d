"""``linear``: a straight TCP line to a frame."""

from __future__ import annotations

from typing import Any, ClassVar

from cellrunner.model.step_kinds import register
from cellrunner.model.task import LinearArgs
from cellrunner.steps._families import FrameLine


@register
class Linear(FrameLine):
    name = "linear"
    order = 3
    args = LinearArgs
    summary = "Straight TCP line to a frame (speed in m/s)."
    example: ClassVar[Any] = {"to": "pallet", "offset": [0, 0, 0.02]}
    colour = "#fc8d62"
