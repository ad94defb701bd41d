"""The task file (SPEC section 4) as pydantic models, and the argument models that
several step kinds share (a move's, a line's, a distance, a grip's).

A step in the file is a one-key mapping ``{KIND: ARGS}`` (or a bare ``KIND`` for steps
without arguments, like ``release``). Each kind's module (:mod:`cellrunner.steps`) names
the model of its arguments and widens its short form (``move: home``, ``wait: 2``,
``lift: 0.1``) before validation.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BeforeValidator, Field, WithJsonSchema, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Pose, Strict
from cellrunner.model.params import Param
from cellrunner.model.pattern import Pattern
from cellrunner.model.units import (
    Force,
    Fraction,
    NonNegativeLength,
    PositiveDuration,
    PositiveLength,
    Speed,
    parse_quantity,
)


def parse_target(value: Any) -> str | list[float]:
    """A TARGET: a frame name, ``home``, or six joint angles in degrees."""
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        if len(value) != 6:
            raise PydanticCustomError(
                "target", f"a joint target needs 6 angles in degrees, got {len(value)}"
            )
        out = []
        for i, v in enumerate(value):
            try:
                out.append(parse_quantity(v, "angle"))
            except PydanticCustomError as exc:
                raise PydanticCustomError("target", f"joint {i + 1}: {exc.message()}") from None
        return out
    raise PydanticCustomError(
        "target", f"expected a frame name, 'home' or 6 joint angles in degrees, got {value!r}"
    )


Target = Annotated[
    str | list[float],
    BeforeValidator(parse_target),
    WithJsonSchema(
        {
            "description": "a frame name, 'home', or 6 joint angles in degrees",
            "anyOf": [
                {"type": "string"},
                {
                    "type": "array",
                    "minItems": 6,
                    "maxItems": 6,
                    "items": {"type": ["number", "string"]},
                },
            ],
        }
    ),
]


class Offset(Pose):
    """An offset in the target frame's axes (m, deg)."""


def widen_offset(value: Any) -> Any:
    """``[dx, dy, dz]`` -> ``{xyz: [dx, dy, dz]}``; anything else as it is."""
    if isinstance(value, list):  # [dx, dy, dz] short form
        return {"xyz": value}
    return value


class MoveArgs(Strict):
    to: Target
    """A frame name, home, or six joint angles in degrees. Example: `home`"""
    offset: Annotated[Offset, Field()] | None = None
    """Offset in the target frame's axes (m, deg), or [dx, dy, dz]. Example: `[0, 0, 0.05]`"""
    speed: Fraction = 1.0
    """Fraction of the joint limits. Example: `0.5`"""
    pattern: Pattern | None = None
    """A grid of targets indexed by a param, offsetting the frame as a pick's does. Example: `{grid: [2, 2], pitch: [0.05, 0.05], index: hole}`"""

    _o = field_validator("offset", mode="before")(lambda cls, v: widen_offset(v))


class ApproachArgs(Strict):
    to: Name
    """Frame to approach. Example: `infeed`"""
    distance: NonNegativeLength = 0.1
    """How far back from the frame along its Z, m. Example: `0.1`"""
    offset: Offset | None = None
    """Offset in the frame's axes (m, deg), or [dx, dy, dz]. Example: `[0, 0.02, 0]`"""
    speed: Fraction = 1.0
    """Fraction of the joint limits. Example: `1.0`"""
    pattern: Pattern | None = None
    """A grid of targets indexed by a param, offsetting the frame as a pick's does. Example: `{grid: [2, 2], pitch: [0.05, 0.05], index: hole}`"""

    _o = field_validator("offset", mode="before")(lambda cls, v: widen_offset(v))


class LinearArgs(Strict):
    to: Name
    """Frame the TCP moves to in a straight line. Example: `infeed`"""
    offset: Offset | None = None
    """Offset in the frame's axes (m, deg), or [dx, dy, dz]. Example: `[0, 0, 0.01]`"""
    speed: Speed | None = None  # m/s; default: the cell's tcp speed limit
    """TCP speed in m/s (default: the cell's TCP speed limit). Example: `0.1`"""
    contact: list[Name] | None = None
    """Fixtures the tool or held part may touch along this line (the walls of a hole). Example: `[hole_wall_x, hole_wall_y]`"""
    clearance: NonNegativeLength | None = None
    """Distance this line keeps from everything else, m (default: the cell's). Example: `0.001`"""
    pattern: Pattern | None = None
    """A grid of targets indexed by a param, offsetting the frame as a pick's does. Example: `{grid: [2, 2], pitch: [0.05, 0.05], index: hole}`"""

    _o = field_validator("offset", mode="before")(lambda cls, v: widen_offset(v))


class DistanceArgs(Strict):
    distance: PositiveLength
    """Distance in m. Example: `0.1`"""
    speed: Speed | None = None
    """TCP speed in m/s (default: the cell's TCP speed limit). Example: `0.25`"""


class ForceWindow(Strict):
    min: Force = 0.0
    """Least load that counts as holding a part, N. Example: `2`"""
    max: Force | None = None
    """Most load allowed, N. Example: `40`"""

    @model_validator(mode="after")
    def _ordered(self) -> ForceWindow:
        if self.max is not None and self.max < self.min:
            raise PydanticCustomError(
                "force", f"force window min {self.min:g} N is above max {self.max:g} N"
            )
        return self


class GripArgs(Strict):
    confirm: Name | None = None
    """Input that must read true within the timeout. Example: `gripper_closed`"""
    force: ForceWindow | None = None
    """Measured load window in N (wrench change, or weight once lifted). Example: `{min: 2, max: 40}`"""
    timeout: PositiveDuration = 1.5
    """Seconds to wait for the confirmation. Example: `1.5`"""


class Retry(Strict):
    attempts: Annotated[int, Field(ge=1, le=20)] = 1
    """Attempts in all (1 = no retry). Example: `3`"""
    between: list[Any] = Field(default_factory=list)  # steps, validated by the loader
    """Primitive steps run before each new attempt. Example: `[release, {retreat: 0.03}]`"""


def at_frame(data: Any) -> Any:
    """``at: {frame: FRAME, offset: POSE_PARAM | {xyz, rpy}}`` -> ``at: FRAME`` plus
    ``at_offset`` (a pose param's name) or ``offset`` (a literal pose)."""
    if not isinstance(data, dict) or not isinstance(data.get("at"), dict):
        return data
    at = dict(data["at"])
    unknown = set(at) - {"frame", "offset"}
    if unknown or "frame" not in at:
        raise PydanticCustomError(
            "at",
            f"'at' is a frame name or {{frame: FRAME, offset: POSE_PARAM}}; got keys {sorted(at)}",
        )
    out = {**data, "at": at["frame"]}
    offset = at.get("offset")
    if isinstance(offset, str):
        out["at_offset"] = offset
    elif offset is not None:
        if data.get("offset") is not None:
            raise PydanticCustomError("at", "give the offset either in 'at' or beside it, not both")
        out["offset"] = offset
    return out


#: ``at``: a frame name, or (widened by :func:`at_frame`) ``{frame, offset}``
AtFrame = Annotated[
    Name,
    WithJsonSchema(
        {
            "description": "a frame name, or {frame: FRAME, offset: POSE_PARAM or {xyz, rpy}}",
            "anyOf": [
                {"type": "string"},
                {
                    "type": "object",
                    "required": ["frame"],
                    "additionalProperties": False,
                    "properties": {
                        "frame": {
                            "type": "string",
                            "description": "the frame",
                            "examples": ["infeed"],
                        },
                        "offset": {
                            "type": ["string", "object", "array"],
                            "description": "a pose param's name, or a literal {xyz, rpy}",
                            "examples": ["part_pose"],
                        },
                    },
                },
            ],
        }
    ),
]


class ProtectiveStopPolicy(Strict):
    resume: bool = False
    """Resume the job after a protective stop (after the controller's 5 s unlock delay). Example: `true`"""
    max: Annotated[int, Field(ge=0, le=10)] = 1
    """Protective stops a job may resume from. Example: `2`"""


class ObstaclePolicy(Strict):
    """What a job does when the watched zone's map blocks its path (SPEC section 12)."""

    wait: PositiveDuration = 10.0
    """How long the arm waits, stopped on its path, for the way to clear before the job ends with 108, s. Example: `10`"""
    replan: bool = False
    """While waiting, plan around the map from where the arm stands (at most once a second). Example: `true`"""
    max_replans: Annotated[int, Field(ge=0, le=100)] = 3
    """Replans a job may make around obstacles before it ends with 108. Example: `3`"""


class TaskFile(Strict):
    """The top level of a task file; ``steps`` are validated one by one by the loader."""

    task: Name
    """Task name, used in logs, the journal and OPC UA StartJob. Example: `pick_place`"""
    description: str | None = None
    """What the task does, for people. Example: `pick a block from the infeed, place it on the pallet`"""
    params: dict[Name, Param] = Field(default_factory=dict)
    """Typed, bounded params a PLC or the CLI supplies, in PLC register order. Example: `{slot: {type: int, min: 0, max: 11, default: 0}}`"""
    steps: Annotated[list[Any], Field(min_length=1)]
    """The steps, in order: {KIND: ARGS} or a bare grip/release. Example: `[{move: home}, {pick: {at: infeed}}, {place: {at: pallet}}]`"""
    on_protective_stop: ProtectiveStopPolicy = Field(default_factory=ProtectiveStopPolicy)
    """What a protective stop does to the job (an e-stop always aborts). Example: `{resume: true, max: 2}`"""
    on_obstacle: ObstaclePolicy = Field(default_factory=ObstaclePolicy)
    """What a job does when an obstacle of the watched zone blocks its path: wait, replan. Example: `{wait: 10, replan: true, max_replans: 3}`"""
    on_error: list[Any] = Field(default_factory=list)
    """Steps run after a failed or aborted job that left the arm able to move. Example: `[{set_output: {door_cmd: false}}, {retreat: 0.05}]`"""
