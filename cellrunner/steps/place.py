"""``place``: approach -> descend -> release -> retreat; the twin judges where the part
ends against the place's target and ``place_tolerance``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import Field, field_validator, model_validator

from cellrunner.model.base import Name, Strict
from cellrunner.model.pattern import Pattern
from cellrunner.model.step import Macro, Step, StepKind
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.task import (
    AtFrame,
    DistanceArgs,
    GripArgs,
    Offset,
    at_frame,
    widen_offset,
)
from cellrunner.model.units import NonNegativeLength, Speed

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.expand import Expansion
    from cellrunner.model.loaded import StepSpec
    from cellrunner.model.references import ReferenceCheck


class PlaceArgs(Strict):
    at: AtFrame
    """Frame where the part is put down, or {frame, offset: POSE_PARAM}. Example: `pallet`"""
    at_offset: Name | None = None
    """Set from `at: {frame, offset: PARAM}`: the pose param giving where to put the part. Example: `drop_pose`"""
    confirm: Name | None = None
    """Input that must read true after the release (part in place). Example: `part_in_fixture`"""
    approach: NonNegativeLength = 0.1
    """Approach distance above the frame along tool -Z, m. Example: `0.1`"""
    retreat: NonNegativeLength | None = None  # default: the approach distance
    """Retreat distance after the release, m (default: the approach distance). Example: `0.1`"""
    offset: Offset | None = None
    """Offset in the frame's axes (m, deg), or [dx, dy, dz]. Example: `[0, 0, 0.005]`"""
    pattern: Pattern | None = None
    """A grid of place positions indexed by a param. Example: `{grid: [3, 4], pitch: [0.07, 0.07], index: slot}`"""
    release: GripArgs = Field(default_factory=GripArgs)
    """How the release is confirmed. Example: `{timeout: 1.0}`"""
    speed: Speed | None = None
    """Descend and retreat speed, m/s. Example: `0.1`"""

    _o = field_validator("offset", mode="before")(lambda cls, v: widen_offset(v))
    _a = model_validator(mode="before")(lambda cls, v: at_frame(v))


@register
class Place(StepKindDef):
    name = "place"
    order = 12
    args = PlaceArgs
    macro = True
    top_level_only = True
    summary = "Macro: approach -> descend -> release -> retreat."
    example: ClassVar[Any] = {
        "at": "pallet",
        "approach": 0.1,
        "pattern": {"grid": [3, 4], "pitch": [0.07, 0.07], "index": "slot"},
    }

    def target_frame(self, args: Any) -> str | None:
        return str(args.at)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        args, path = spec.args, spec.path
        refs.at_frame(spec)
        if args.confirm is not None:
            refs.input(args.confirm, path + ("confirm",))
        refs.needs_gripper = True
        if args.release.confirm is not None:
            refs.input(args.release.confirm, path + ("release", "confirm"))

    def expand(self, builder: Expansion, spec: StepSpec, args: Any) -> None:
        a: PlaceArgs = args
        T, name = builder.target(a.at, a.offset, a.pattern, a.at_offset)
        macro, path = Macro("place", name), spec.path
        builder.approach_and_descend(a, T, name, path, macro)
        release = (
            a.release if a.confirm is None else a.release.model_copy(update={"confirm": a.confirm})
        )
        tolerance = builder.cell.place_tolerance
        # the twin compares the part's pose with this once the gripper has left it
        check = {
            "place_check": {"T_world_tcp": T, "tolerance": (tolerance.distance, tolerance.angle)}
        }
        # where the earlier slots of its pattern put their parts (what this one may rest on)
        earlier = earlier_slots(builder, a)
        back = a.retreat if a.retreat is not None else a.approach
        extra = {"earlier_slots": earlier, **({} if back > 0 else check)}
        builder.steps.append(
            Step(builder.next_index(), StepKind.RELEASE, name, release, path, macro, extra=extra)
        )
        if back > 0:
            away = DistanceArgs(distance=back, speed=a.speed)
            builder.steps.append(
                Step(builder.next_index(), StepKind.RETREAT, name, away, path, macro, extra=check)
            )


def earlier_slots(builder: Expansion, a: PlaceArgs) -> list[np.ndarray]:
    """The TCP targets of the slots before this one in the place's pattern (none without
    a pattern): the parts earlier jobs put there."""
    if a.pattern is None:
        return []
    slot = int(builder.params[a.pattern.index])
    out = []
    for earlier in range(slot):
        was = builder.with_params({**builder.params, a.pattern.index: earlier})
        out.append(was.target(a.at, a.offset, a.pattern, a.at_offset)[0])
    return out
