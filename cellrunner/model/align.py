"""Arguments of ``align`` (SPEC section 12, visual alignment): a camera looks at an ArUco
marker on the part (or fixture) at the next step's target frame, and the arm corrects the
TCP until the marker is where that frame says, within ``tolerance``.

The correction is a pose in the target frame's axes (m, deg, XYZ fixed-axis), applied to
the frame for the steps after the align that aim at it. ``max_correction`` bounds it on
each axis (``[x, y, z]`` m, ``[r, p, y]`` deg, symmetric): ``check`` proves the task for
the centre and every corner of that box, and a measured correction outside it fails the
step (result 3).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import Field

from cellrunner.model.base import Name, Strict
from cellrunner.model.marker import Marker as Marker
from cellrunner.model.marker import MarkerId
from cellrunner.model.step_kinds import kind_of
from cellrunner.model.units import Angle, NonNegativeLength, PositiveLength

if TYPE_CHECKING:
    import numpy as np

Vec3NonNeg = Annotated[list[NonNegativeLength], Field(min_length=3, max_length=3)]
Rpy3 = Annotated[list[Annotated[Angle, Field(ge=0, le=45)]], Field(min_length=3, max_length=3)]


class Tolerance(Strict):
    xyz: PositiveLength = 0.001
    """Largest remaining position error, m. Example: `0.001`"""
    rpy: Annotated[Angle, Field(gt=0)] = 0.5
    """Largest remaining rotation error, deg. Example: `0.5`"""


class MaxCorrection(Strict):
    xyz: Vec3NonNeg = Field(default_factory=lambda: [0.01, 0.01, 0.0])
    """Largest correction along the frame's x, y, z, m (either way). Example: `[0.015, 0.015, 0]`"""
    rpy: Rpy3 = Field(default_factory=lambda: [0.0, 0.0, 5.0])
    """Largest correction about the frame's x, y, z, deg (either way). Example: `[0, 0, 8]`"""


class AlignArgs(Strict):
    """``align: {camera, marker, tolerance, max_correction, attempts}``."""

    camera: Name
    """The camera that sees the marker (a `cameras:` entry; on the flange, or fixed). Example: `wrist`"""
    marker: MarkerId | Marker
    """The id of a marker the part (or a fixture) at the target carries (its `markers:`), or the marker and where it sits in the target frame (on the part at the target). Example: `7`"""
    tolerance: Tolerance = Field(default_factory=Tolerance)
    """When the marker is where the step expects it. Example: `{xyz: 0.001, rpy: 0.5}`"""
    max_correction: MaxCorrection = Field(default_factory=MaxCorrection)
    """The box of corrections `check` proves; beyond it the step fails (3). Example: `{xyz: [0.015, 0.015, 0], rpy: [0, 0, 8]}`"""
    attempts: Annotated[int, Field(ge=1, le=10)] = 3
    """Looks at most (each look after the first follows a short verified move). Example: `3`"""
    look: bool = True
    """A camera on the flange first moves onto the marker's axis, `standoff` away (a planned move); false: it looks from where the arm stands. Example: `true`"""
    standoff: PositiveLength | None = None
    """How far from the marker the camera looks, m (default: the marker spans 10 % of the picture's height, at least 0.1 m). Example: `0.2`"""

    def box(self) -> tuple[list[float], list[float]]:
        """The correction box as (min, max), six values each: m then deg."""
        high = [*self.max_correction.xyz, *self.max_correction.rpy]
        return [-v for v in high], high


@dataclass(frozen=True)
class Sighting:
    """A marker seen by a camera: the rays through its four corners (camera frame, 4 x 3,
    z = 1; in the order of :func:`cellrunner.vision.marker.corner_points`) and its pose
    from them (T_camera_marker, m; None when it could not be solved)."""

    rays: np.ndarray
    T_camera_marker: np.ndarray | None


def target_frame(spec: Any) -> str | None:
    """The frame a step aims at (None: a joint target, home, a relative move, no motion)."""
    return kind_of(spec.kind).target_frame(spec.args)


def aligned_frame(specs: Sequence[Any], index: int) -> str | None:
    """The frame the align at ``specs[index]`` corrects: the first later step's target."""
    for spec in specs[index + 1 :]:
        frame = target_frame(spec)
        if frame is not None:
            return frame
    return None
