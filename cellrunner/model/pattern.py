"""A ``pattern``: a grid of targets a param picks from (SPEC section 4), on any step that
takes a frame target (pick, place, move, approach, descend, linear, insert)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Strict
from cellrunner.model.units import Angle, Length

if TYPE_CHECKING:
    import numpy as np


class Pattern(Strict):
    """A grid of slots: ``grid: [rows, cols]`` or ``[rows, cols, layers]``.

    Slot ``k`` -> layer ``k // (rows*cols)``, row ``(k % (rows*cols)) // cols``,
    col ``k % cols``; rows step along the frame's X by ``pitch[0]``, columns along its
    Y by ``pitch[1]``, layers straight up (world +Z) by ``pitch[2]`` (or ``layers`` and
    ``layer_pitch``, SPEC section 13). ``turn``: layer k turns by ``turn[k % len(turn)]``
    deg about the frame's Z, its grid re-laid in the turned axes (interlocked layers).
    """

    grid: Annotated[list[Annotated[int, Field(ge=1, le=1000)]], Field(min_length=2, max_length=3)]
    """[rows, cols] or [rows, cols, layers]. Example: `[3, 4]`"""
    pitch: Annotated[list[Length], Field(min_length=2, max_length=3)]
    """Spacing in m along the frame's X (rows), Y (columns) and world +Z (layers). Example: `[0.07, 0.07]`"""
    index: Name
    """The param that picks the slot (0-based). Example: `slot`"""
    layers: Annotated[int, Field(ge=1, le=1000)] | None = None
    """How many layers, stacked by `layer_pitch` (the same as a third grid entry). Example: `3`"""
    layer_pitch: Length | None = None
    """Spacing of the layers in m, straight up (world +Z). Example: `0.12`"""
    turn: Annotated[list[Angle], Field(min_length=1, max_length=100)] | None = None
    """Layer k turns by `turn[k % len(turn)]` deg about the frame's Z (interlocked layers). Example: `[0, 90]`"""

    @model_validator(mode="after")
    def _dims(self) -> Pattern:
        if len(self.grid) == 3 and len(self.pitch) != 3:
            raise PydanticCustomError("pattern", "a grid with layers needs 3 pitches [x, y, z]")
        if self.layers is not None and len(self.grid) == 3:
            raise PydanticCustomError(
                "pattern", "give the layers once: a third grid entry or layers, not both"
            )
        if self.layers is not None and self.layers > 1 and self.layer_pitch is None:
            raise PydanticCustomError("pattern", "layers need a layer_pitch (m)")
        if self.layer_pitch is not None and self.layers is None:
            raise PydanticCustomError("pattern", "layer_pitch needs layers")
        return self

    @property
    def layer_count(self) -> int:
        if self.layers is not None:
            return self.layers
        return self.grid[2] if len(self.grid) == 3 else 1

    @property
    def slots(self) -> int:
        return self.grid[0] * self.grid[1] * self.layer_count

    def offset_m(self, slot: int) -> tuple[float, float, float, float]:
        """(dx, dy) in the layer's (turned) axes and dz straight up, for ``slot``; plus
        layer."""
        rows, cols = self.grid[0], self.grid[1]
        layer, rest = divmod(slot, rows * cols)
        row, col = divmod(rest, cols)
        pitch_z = self.pitch[2] if len(self.pitch) == 3 else (self.layer_pitch or 0.0)
        return row * self.pitch[0], col * self.pitch[1], layer * pitch_z, layer

    def turn_deg(self, layer: int) -> float:
        """How far layer ``layer`` turns about the frame's Z (deg)."""
        return float(self.turn[layer % len(self.turn)]) if self.turn else 0.0

    def T_frame_slot(self, slot: int) -> np.ndarray:
        """Slot ``slot`` in the frame's axes (4x4, m), its layer's height excepted (that
        is straight up in the world): the layer turned about the frame's Z, then the row
        and column laid along the turned X and Y."""
        dx, dy, _, layer = self.offset_m(slot)
        a = math.radians(self.turn_deg(int(layer)))
        c, s = math.cos(a), math.sin(a)
        import numpy as np  # lazily: validating a file imports no numpy

        T = np.eye(4)
        T[:2, :2] = ((c, -s), (s, c))
        T[:2, 3] = (c * dx - s * dy, s * dx + c * dy)
        return T
