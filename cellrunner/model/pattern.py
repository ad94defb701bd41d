"""A ``pattern``: a grid of targets a param picks from (SPEC section 4), on any step that
takes a frame target (pick, place, move, approach, descend, linear, insert)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Strict
from cellrunner.model.units import Length


class Pattern(Strict):
    """A grid of slots: ``grid: [rows, cols]`` or ``[rows, cols, layers]``.

    Slot ``k`` -> layer ``k // (rows*cols)``, row ``(k % (rows*cols)) // cols``,
    col ``k % cols``; rows step along the frame's X by ``pitch[0]``, columns along its
    Y by ``pitch[1]``, layers straight up (world +Z) by ``pitch[2]``.
    """

    grid: Annotated[list[Annotated[int, Field(ge=1, le=1000)]], Field(min_length=2, max_length=3)]
    """[rows, cols] or [rows, cols, layers]. Example: `[3, 4]`"""
    pitch: Annotated[list[Length], Field(min_length=2, max_length=3)]
    """Spacing in m along the frame's X (rows), Y (columns) and world +Z (layers). Example: `[0.07, 0.07]`"""
    index: Name
    """The param that picks the slot (0-based). Example: `slot`"""

    @model_validator(mode="after")
    def _dims(self) -> Pattern:
        if len(self.grid) == 3 and len(self.pitch) != 3:
            raise PydanticCustomError("pattern", "a grid with layers needs 3 pitches [x, y, z]")
        return self

    @property
    def slots(self) -> int:
        n = 1
        for g in self.grid:
            n *= g
        return n

    def offset_m(self, slot: int) -> tuple[float, float, float, float]:
        """(dx, dy) in the frame's axes and dz straight up, for ``slot``; plus layer."""
        rows, cols = self.grid[0], self.grid[1]
        layer, rest = divmod(slot, rows * cols)
        row, col = divmod(rest, cols)
        dz = layer * (self.pitch[2] if len(self.pitch) == 3 else 0.0)
        return row * self.pitch[0], col * self.pitch[1], dz, layer
