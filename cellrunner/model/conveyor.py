"""A cell's ``conveyors:`` (SPEC section 13): the path parts ride, the encoder that measures
it, the photo-eye that latches each part, and the window the arm may work in.

```yaml
conveyors:
  belt:
    path: {line: {from: [0.9, -0.6, 0.80], to: [0.9, 0.8, 0.80]}}
    encoder: {source: ur, index: 0, ticks_per_m: 4000}
    trigger: {input: part_at_eye}
    eye_to_frame: 0.35
    frame: belt_pick
    window: [-0.10, 0.45]
    speed_max: 0.30
```

Distances along a path (``s_m``) are measured from its start (``from``), in m; on an arc
the belt turns about the arc's centre, counter-clockwise seen from above when ``to_deg >
from_deg``. :func:`T_world_shift` is the rigid motion of everything on the belt when it
travels a distance. Pure data and numpy; names are checked by :mod:`cellrunner.model.conveyor_checks`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Strict, Vec3
from cellrunner.model.units import Angle, Length, NonNegativeLength, PositiveLength, Speed

if TYPE_CHECKING:
    import numpy as np

#: the PLC's encoder registers (uint32, high word first): 20-21 for the first conveyor,
#: up to 28-29
PLC_ENCODER_REGISTERS = range(20, 30, 2)
#: the UR controller's RTDE output int register the program relays pulse decoder 0's tick
#: count into (decoder 1: the next one); 18-19 lie in ur_rtde's user range (12-19)
UR_TICK_REGISTER = 18
#: how far a conveyor's frame may lie off its path, m, before the cell file is refused
FRAME_ON_PATH_M = 0.02


class LinePath(Strict):
    from_: Vec3 = Field(alias="from")
    """Where the belt's path starts (upstream), in the world, m. Example: `[0.9, -0.6, 0.8]`"""
    to: Vec3
    """Where it ends (downstream), m. Example: `[0.9, 0.8, 0.8]`"""

    @model_validator(mode="after")
    def _long_enough(self) -> LinePath:
        if math.dist(self.from_, self.to) < 1e-3:
            raise PydanticCustomError(
                "conveyor", "a line path needs from and to 1 mm apart or more"
            )
        return self


class ArcPath(Strict):
    centre: Vec3
    """The centre of a round table, in the world, m (the belt turns about world Z). Example: `[0.6, 0, 0.8]`"""
    radius: PositiveLength
    """Radius of the parts' circle, m. Example: `0.4`"""
    from_deg: Angle
    """Where the path starts, deg about Z from world X. Example: `-90`"""
    to_deg: Angle
    """Where it ends, deg (above from_deg: the table turns counter-clockwise). Example: `90`"""

    @model_validator(mode="after")
    def _turns(self) -> ArcPath:
        span = abs(self.to_deg - self.from_deg)
        if not 1e-3 <= span <= 360.0:
            raise PydanticCustomError(
                "conveyor", f"an arc path turns between 0 and 360 deg, not {span:g} deg"
            )
        return self


class ConveyorPath(Strict):
    """Exactly one of ``line`` and ``arc``."""

    line: LinePath | None = None
    """A straight belt from `from` to `to`. Example: `{from: [0.9, -0.6, 0.8], to: [0.9, 0.8, 0.8]}`"""
    arc: ArcPath | None = None
    """A round table. Example: `{centre: [0.6, 0, 0.8], radius: 0.4, from_deg: -90, to_deg: 90}`"""

    @model_validator(mode="after")
    def _one(self) -> ConveyorPath:
        given = [k for k in ("line", "arc") if getattr(self, k) is not None]
        if len(given) != 1:
            raise PydanticCustomError(
                "conveyor",
                f"a path needs exactly one of line, arc; got {', '.join(given) or 'none'}",
            )
        return self

    @property
    def length_m(self) -> float:
        if self.line is not None:
            return math.dist(self.line.from_, self.line.to)
        assert self.arc is not None
        return abs(math.radians(self.arc.to_deg - self.arc.from_deg)) * self.arc.radius


class Encoder(Strict):
    """How the belt's travel is measured: the controller's pulse decoder (``ur``), the
    PLC's registers (``plc``), or a constant speed with no encoder (``speed``)."""

    source: Literal["ur", "plc", "speed"]
    """ur (the controller's pulse decoder), plc (registers 20-29) or speed (constant, no encoder). Example: `ur`"""
    index: Annotated[int, Field(ge=0, le=1)] = 0
    """ur: the pulse decoder's encoder index, 0 or 1. Example: `0`"""
    ticks_per_m: Annotated[float, Field(gt=0)] | None = None
    """ur and plc: encoder ticks per m of belt travel. Example: `4000`"""
    register_: int | None = Field(default=None, alias="register")
    """plc: the first of the two holding registers (uint32, high word first): 20, 22, ... 28. Example: `20`"""
    mps: Speed | None = None
    """speed: the belt's constant speed, m/s. Example: `0.25`"""

    @model_validator(mode="after")
    def _fields_of_source(self) -> Encoder:
        need = {"ur": ("ticks_per_m",), "plc": ("register", "ticks_per_m"), "speed": ("mps",)}
        missing = [k for k in need[self.source] if getattr(self, _attr(k)) is None]
        if missing:
            raise PydanticCustomError(
                "conveyor", f"encoder source {self.source} needs {', '.join(missing)}"
            )
        foreign = [
            k
            for k in ("ticks_per_m", "register", "mps")
            if getattr(self, _attr(k)) is not None and k not in need[self.source]
        ]
        if foreign:
            raise PydanticCustomError(
                "conveyor",
                f"encoder source {self.source} takes no {', '.join(foreign)} "
                f"(it takes {', '.join(need[self.source])})",
            )
        if self.register_ is not None and self.register_ not in PLC_ENCODER_REGISTERS:
            raise PydanticCustomError(
                "conveyor",
                f"encoder register {self.register_} is not one of "
                f"{', '.join(str(r) for r in PLC_ENCODER_REGISTERS)} (two registers each, 20-29)",
            )
        return self


def _attr(key: str) -> str:
    """The attribute of an encoder's key (``register`` is ``register_``: pydantic's own)."""
    return "register_" if key == "register" else key


class Trigger(Strict):
    input: Name
    """The photo-eye's input: each rising edge latches a part at the eye. Example: `part_at_eye`"""


Window = Annotated[list[Length], Field(min_length=2, max_length=2)]


class Conveyor(Strict):
    """A belt or round table that carries parts past the arm."""

    path: ConveyorPath
    """The path parts ride: a line or an arc. Example: `{line: {from: [0.9, -0.6, 0.8], to: [0.9, 0.8, 0.8]}}`"""
    encoder: Encoder
    """How the belt's travel is measured. Example: `{source: ur, index: 0, ticks_per_m: 4000}`"""
    trigger: Trigger
    """The photo-eye that latches each part. Example: `{input: part_at_eye}`"""
    eye_to_frame: NonNegativeLength
    """Distance along the path from the eye to `frame`, m. Example: `0.35`"""
    frame: Name
    """The cell frame where a latched part is once it has travelled eye_to_frame. Example: `belt_pick`"""
    window: Window
    """[start, end] along the path relative to `frame`, m: where the arm may work on a part. Example: `[-0.10, 0.45]`"""
    speed_max: Speed
    """The top belt speed the cell is proved for, m/s. Example: `0.30`"""

    @model_validator(mode="after")
    def _window_order(self) -> Conveyor:
        if self.encoder.mps is not None and self.encoder.mps > self.speed_max + 1e-12:
            raise PydanticCustomError(
                "conveyor",
                f"the belt runs at {self.encoder.mps:g} m/s (encoder mps), above the "
                f"speed_max {self.speed_max:g} m/s the cell is proved for",
            )
        lo, hi = self.window
        if not lo < hi:
            raise PydanticCustomError(
                "conveyor", f"window [{lo:g}, {hi:g}] m must run from its start to a later end"
            )
        return self


# ------------------------------------------------------------------ geometry


def s_of_point_m(path: ConveyorPath, p_world_m: Sequence[float]) -> tuple[float, float]:
    """(distance along ``path`` of the point nearest ``p_world_m``, its distance from
    the path seen from above), m: a part rides above the path at any height. The first
    may lie beyond the path's ends (then the second is measured from its extension).
    Plain Python: ``validate`` checks frames with it without numpy."""
    x, y, _ = (float(v) for v in p_world_m)
    if path.line is not None:
        a, b = path.line.from_, path.line.to
        length = math.dist(a, b)
        u = [(bi - ai) / length for ai, bi in zip(a, b, strict=True)]
        s = (x - a[0]) * u[0] + (y - a[1]) * u[1] + (float(p_world_m[2]) - a[2]) * u[2]
        off = math.hypot(x - (a[0] + s * u[0]), y - (a[1] + s * u[1]))
        return s, off
    arc = path.arc
    assert arc is not None
    dx, dy = x - arc.centre[0], y - arc.centre[1]
    sign = 1.0 if arc.to_deg > arc.from_deg else -1.0
    turn = (math.degrees(math.atan2(dy, dx)) - arc.from_deg) * sign
    gap = (360.0 - abs(arc.to_deg - arc.from_deg)) / 2  # half the way round outside the arc
    turn = (turn + gap) % 360.0 - gap  # from the start, in [-gap, span + gap)
    return math.radians(turn) * arc.radius, abs(math.hypot(dx, dy) - arc.radius)


def T_world_shift(path: ConveyorPath, distance_m: float) -> np.ndarray:
    """The rigid motion (4x4, world) of anything riding the belt as it travels
    ``distance_m`` along ``path``: a translation along a line, a turn about the arc's
    centre."""
    import numpy as np

    T = np.eye(4)
    if path.line is not None:
        a, b = np.asarray(path.line.from_, float), np.asarray(path.line.to, float)
        T[:3, 3] = (b - a) / np.linalg.norm(b - a) * distance_m
        return T
    arc = path.arc
    assert arc is not None
    sign = 1.0 if arc.to_deg > arc.from_deg else -1.0
    theta = sign * distance_m / arc.radius
    c, s = math.cos(theta), math.sin(theta)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    centre = np.asarray(arc.centre, float)
    T[:3, :3] = R
    T[:3, 3] = centre - R @ centre
    return T


def belt_velocity_mps(path: ConveyorPath, p_world_m: np.ndarray, speed_mps: float) -> np.ndarray:
    """The velocity (m/s, world) of the belt's point at ``p_world_m`` at ``speed_mps``
    (the speed along the path; on an arc, at its radius)."""
    import numpy as np

    if path.line is not None:
        a, b = np.asarray(path.line.from_, float), np.asarray(path.line.to, float)
        return np.asarray((b - a) / np.linalg.norm(b - a) * speed_mps)
    arc = path.arc
    assert arc is not None
    sign = 1.0 if arc.to_deg > arc.from_deg else -1.0
    omega = sign * speed_mps / arc.radius
    d = np.asarray(p_world_m, float) - np.asarray(arc.centre, float)
    return np.array([-omega * d[1], omega * d[0], 0.0])
