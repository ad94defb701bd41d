"""Arguments of the force steps (SPEC section 11): ``move_until_contact`` and ``insert``.

Both are straight TCP lines that ``check`` verifies to their full length (``max_distance``,
``depth``); on every backend the engine streams that approved line and stops it at the
first wrist force above the step's limit (a guarded servo).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Strict
from cellrunner.model.pattern import Pattern
from cellrunner.model.units import Force, Length, NonNegativeLength, PositiveLength, Speed


class MoveUntilContactArgs(Strict):
    """Move along ``direction`` (in the ``frame`` axes: the TCP's or the world's) at
    ``speed`` (m/s) until the wrist force rises by ``force`` (N); fail when no contact
    comes within ``max_distance`` (m)."""

    direction: Annotated[list[float], Field(min_length=3, max_length=3)] = Field(
        default_factory=lambda: [0.0, 0.0, 1.0]
    )
    """Direction of travel in the `frame` axes (normalised). Example: `[0, 0, 1]`"""
    frame: Literal["tool", "world"] = "tool"
    """Axes of `direction`: the TCP's (tool) or the world's. Example: `tool`"""
    speed: Speed = 0.01
    """Speed along the line, m/s. Example: `0.01`"""
    force: Annotated[Force, Field(gt=0)] = 10.0
    """Rise of the wrist force, N, that counts as contact. Example: `10`"""
    max_distance: PositiveLength = 0.05
    """The step fails when no contact comes within this distance, m. Example: `0.05`"""

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v: list[float]) -> list[float]:
        norm = sum(x * x for x in v) ** 0.5
        if norm < 1e-9:
            raise PydanticCustomError(
                "direction", "direction [0, 0, 0] has no length; e.g. [0, 0, 1] (tool Z)"
            )
        return [x / norm for x in v]


class ForceLimit(Strict):
    max: Annotated[Force, Field(gt=0)]
    """Wrist force, N, above which the insert stops. Example: `20`"""
    min: Annotated[Force, Field(gt=0)] | None = None
    """A press fit: the wrist force, N, the insert must build up on its way in, else it failed (3). Example: `40`"""

    @model_validator(mode="after")
    def _order(self) -> ForceLimit:
        low, high = self.min, self.max  # (a param's name is judged with its value)
        if isinstance(low, float | int) and isinstance(high, float | int) and low >= high:
            raise PydanticCustomError(
                "force", f"force min {self.min:g} N is not below max {self.max:g} N"
            )
        return self


class InsertArgs(Strict):
    """Move straight to FRAME ``to`` and on along its Z by ``depth`` (m) at ``speed``
    (m/s), stopping when the wrist force rises above ``force.max`` (N). The depth reached
    past the frame must lie in ``expect_depth`` (m; default: the full depth, -1 mm), else
    the place failed (3)."""

    to: Name
    """Frame at the mouth of the hole. Example: `hole`"""
    depth: PositiveLength
    """How far past the frame along its Z to go, m. Example: `0.02`"""
    speed: Speed = 0.005
    """Insertion speed, m/s. Example: `0.005`"""
    force: ForceLimit
    """Force limit of the insertion; `min` declares a press fit. Example: `{max: 20}`"""
    expect_depth: Annotated[list[Length], Field(min_length=2, max_length=2)] | None = None
    """Depth window [min, max] in m the insert must end in, else the place failed (3). Example: `[0.018, 0.021]`"""
    contact: list[Name] | None = None
    """Fixtures the tool or held part may touch along this line (the walls of a hole). Example: `[hole_wall_x, hole_wall_y]`"""
    clearance: NonNegativeLength | None = None
    """Distance this line keeps from everything else, m (default: the cell's). Example: `0.001`"""
    pattern: Pattern | None = None
    """A grid of holes indexed by a param, offsetting the frame as a pick's does. Example: `{grid: [2, 2], pitch: [0.05, 0.05], index: hole}`"""

    @model_validator(mode="after")
    def _window(self) -> InsertArgs:
        if self.expect_depth is not None:
            lo, hi = self.expect_depth
            if lo > hi:
                raise PydanticCustomError(
                    "expect_depth", f"expect_depth min {lo:g} m is above max {hi:g} m"
                )
            if lo > self.depth:
                raise PydanticCustomError(
                    "expect_depth",
                    f"expect_depth min {lo:g} m is deeper than the insert's depth {self.depth:g} m",
                )
        return self

    @property
    def depth_window_m(self) -> tuple[float, float]:
        if self.expect_depth is not None:
            return self.expect_depth[0], self.expect_depth[1]
        return self.depth - 0.001, self.depth + 0.001
