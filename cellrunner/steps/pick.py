"""``pick``: approach -> descend -> grip (with its retries) -> lift."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import Field, field_validator, model_validator

from cellrunner.model.base import Name, Strict
from cellrunner.model.pattern import Pattern
from cellrunner.model.step import Macro, RetryPlan, Step, StepKind
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.task import (
    AtFrame,
    DistanceArgs,
    GripArgs,
    Offset,
    Retry,
    at_frame,
    widen_offset,
)
from cellrunner.model.units import NonNegativeLength, Speed

if TYPE_CHECKING:
    from cellrunner.model.expand import Expansion
    from cellrunner.model.loaded import StepSpec
    from cellrunner.model.references import ReferenceCheck


class PickArgs(Strict):
    at: AtFrame
    """Frame of the part (where the TCP grips it), or {frame, offset: POSE_PARAM}. Example: `infeed`"""
    at_offset: Name | None = None
    """Set from `at: {frame, offset: PARAM}`: the pose param giving where the part is. Example: `part_pose`"""
    approach: NonNegativeLength = 0.1
    """Approach distance above the frame along tool -Z, m. Example: `0.1`"""
    lift: NonNegativeLength | None = None  # default: the approach distance
    """Lift distance after the grip, m (default: the approach distance). Example: `0.1`"""
    offset: Offset | None = None
    """Offset in the frame's axes (m, deg), or [dx, dy, dz]. Example: `[0, 0, 0.005]`"""
    pattern: Pattern | None = None
    """A grid of pick positions indexed by a param. Example: `{grid: [3, 4], pitch: [0.07, 0.07], index: slot}`"""
    grip: GripArgs = Field(default_factory=GripArgs)
    """How the grip is confirmed. Example: `{confirm: gripper_closed, force: {min: 2, max: 40}, timeout: 1.5}`"""
    retry: Retry | None = None
    """Retries of a failed grip. Example: `{attempts: 3, between: [release, {retreat: 0.03}]}`"""
    speed: Speed | None = None  # descend/lift speed, m/s
    """Descend and lift speed, m/s. Example: `0.1`"""

    _o = field_validator("offset", mode="before")(lambda cls, v: widen_offset(v))
    _a = model_validator(mode="before")(lambda cls, v: at_frame(v))


@register
class Pick(StepKindDef):
    name = "pick"
    order = 11
    args = PickArgs
    macro = True
    top_level_only = True
    summary = "Macro: approach -> descend -> grip -> lift."
    example: ClassVar[Any] = {
        "at": "infeed",
        "approach": 0.1,
        "grip": {"confirm": "gripper_closed"},
    }

    def target_frame(self, args: Any) -> str | None:
        return str(args.at)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.at_frame(spec)
        refs.needs_gripper = True
        if spec.args.grip.confirm is not None:
            refs.input(spec.args.grip.confirm, spec.path + ("grip", "confirm"))

    def expand(self, builder: Expansion, spec: StepSpec, args: Any) -> None:
        a: PickArgs = args
        T, name = builder.target(a.at, a.offset, a.pattern, a.at_offset)
        macro, path = Macro("pick", name), spec.path
        builder.approach_and_descend(a, T, name, path, macro)
        descend_i = builder.next_index() - 1
        retry = None
        if a.retry is not None and a.retry.attempts > 1:
            between = tuple(
                builder.primitive(
                    s.kind, s.bind(builder.specs, builder.params), s.path, descend_i + 1, macro
                )
                for s in spec.between
            )
            retry = RetryPlan(a.retry.attempts, between, descend_i)
        extra = {"part_at": a.at, **builder.part_pose(a.at, a.pattern, a.at_offset)}
        builder.steps.append(
            Step(
                builder.next_index(),
                StepKind.GRIP,
                name,
                a.grip,
                path,
                macro,
                retry=retry,
                extra=extra,
            )
        )
        lift = a.lift if a.lift is not None else a.approach
        if lift > 0:
            up = DistanceArgs(distance=lift, speed=a.speed)
            builder.steps.append(Step(builder.next_index(), StepKind.LIFT, name, up, path, macro))
