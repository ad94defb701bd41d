"""The cell's ``sim:`` block (SPEC section 11): how the twin drives inputs in rehearsal
(``dry-run`` and ``twin``), where on the line a conveyor, a door or a machine would.

```yaml
sim:
  inputs:
    part_present: {part_at: infeed}                  # true while a part lies at the frame
    door_open: {follows: door_cmd, delay: 1.5}       # the output's value, delay s later
    cycle_done: {pulse_after: cnc_start, delay: 20, width: 0.5}  # a pulse after the output rose
```

Names are the cell's IO names; :func:`cellrunner.model.checks.check_sim_block` checks them against the cell.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import BoxShape, CylinderShape, Name, Pose, Strict
from cellrunner.model.units import Duration, NonNegativeLength, PositiveDuration, PositiveLength

if TYPE_CHECKING:
    from collections.abc import Mapping

    from cellrunner.model.conveyor import Conveyor


class InputRule(Strict):
    """One input's rule: exactly one of ``part_at``, ``follows``, ``pulse_after``."""

    part_at: Name | None = None
    """True while a part lies at this frame (its centre within `within` of where a part
    `at:` this frame sits: at the frame for jaws, under it by half its height for suction).
    Example: `infeed`"""
    within: PositiveLength = 0.02
    """How close a part's centre must be to where it lies at the `part_at` frame, m. Example: `0.02`"""
    follows: Name | None = None
    """Takes this output's value `delay` s later. Example: `door_cmd`"""
    pulse_after: Name | None = None
    """Pulses `delay` s after this output turns on, for `width` s. Example: `cnc_start`"""
    delay: Duration = 0.0
    """Delay of `follows` and `pulse_after`, s. Example: `1.5`"""
    width: PositiveDuration = 0.5
    """Pulse width of `pulse_after`, s. Example: `0.5`"""
    invert: bool = False
    """Drive the input inverted. Example: `false`"""

    @model_validator(mode="after")
    def _one_rule(self) -> InputRule:
        given = [k for k in ("part_at", "follows", "pulse_after") if getattr(self, k) is not None]
        if len(given) != 1:
            raise PydanticCustomError(
                "sim",
                f"an input rule needs exactly one of part_at, follows, pulse_after; got "
                f"{', '.join(given) or 'none'}",
            )
        return self


class Intruder(Strict):
    """An object the cell file does not know, put into the twin ``appear`` s after each job
    starts and taken away ``leave`` s after it (never, without ``leave``); only the twin's
    depth cameras reveal it (SPEC section 12)."""

    name: Name
    """Intruder name, for reports. Example: `tote`"""
    box: BoxShape | None = None
    """A box centred on the pose. Example: `{size: [0.4, 0.3, 0.2]}`"""
    cylinder: CylinderShape | None = None
    """A cylinder along the pose's Z axis, centred on it. Example: `{radius: 0.05, length: 0.6}`"""
    pose: Pose | None = None
    """Where it stands in the world, m and deg. Example: `{xyz: [0.5, 0.1, 1.0]}`"""
    at: Name | None = None
    """A frame it stands at instead (its centre at the frame). Example: `infeed`"""
    appear: Duration = 0.0
    """When it appears, s after the job starts. Example: `1.5`"""
    leave: PositiveDuration | None = None
    """When it is taken away, s after the job starts (never when absent). Example: `5.5`"""

    @model_validator(mode="after")
    def _one_of_each(self) -> Intruder:
        shapes = [k for k in ("box", "cylinder") if getattr(self, k) is not None]
        if len(shapes) != 1:
            raise PydanticCustomError(
                "sim",
                f"an intruder needs exactly one of box, cylinder; got {', '.join(shapes) or 'none'}",
            )
        if (self.pose is None) == (self.at is None):
            raise PydanticCustomError("sim", "an intruder needs exactly one of pose, at (a frame)")
        if self.leave is not None and self.leave <= self.appear:
            raise PydanticCustomError(
                "sim",
                f"leave {self.leave:g} s must come after appear {self.appear:g} s",
            )
        return self


class Feed(Strict):
    """A new part at its frame before each job, in rehearsal (``dry-run``, ``twin``,
    ``serve --backend sim``): a conveyor bringing the next one (SPEC section 12)."""

    part: Name
    """The cell's part a fed one is a copy of. Example: `carton`"""
    at: Name | None = None
    """The frame it is put at (as a part `at:` that frame lies). Example: `infeed`"""
    conveyor: Name | None = None
    """Instead of `at`: the conveyor that brings it (SPEC section 13). Example: `belt`"""
    every: PositiveDuration | None = None
    """With `conveyor`: a part every this many s. Example: `2.0`"""
    jitter: NonNegativeLength = 0.0
    """With `conveyor`: how far a part lies from its even spacing, m (uniform, +-). Example: `0.02`"""

    @model_validator(mode="after")
    def _one_source(self) -> Feed:
        if (self.at is None) == (self.conveyor is None):
            raise PydanticCustomError("sim", "a feed needs exactly one of at (a frame), conveyor")
        return self

    def frame(self, conveyors: Mapping[str, Conveyor]) -> str:
        """The frame a fed part lies at: ``at``, or the frame of its conveyor (one of
        the cell's ``conveyors``)."""
        if self.at is not None:
            return self.at
        assert self.conveyor is not None
        return conveyors[self.conveyor].frame


class SimBlock(Strict):
    feed: Feed | None = None
    """A new part at its frame before each job. Example: `{part: carton, at: infeed}`"""
    inputs: dict[Name, InputRule] = Field(default_factory=dict)
    """Input names to the rule that drives them in rehearsal. Example: `{part_present: {part_at: infeed}}`"""
    depth_noise: NonNegativeLength = 0.0
    """Standard deviation of the noise on the twin's depth images, m. Example: `0.002`"""
    intruders: list[Intruder] = Field(default_factory=list)
    """Objects the cell file does not know, put into the twin while a job runs; only depth cameras see them. Example: `[{name: tote, box: {size: [0.4, 0.3, 0.2]}, pose: {xyz: [0.5, 0.1, 1.0]}, appear: 1.0, leave: 5.0}]`"""
