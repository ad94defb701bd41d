"""Gripper timing, shared by the planned cycle time and the engine so that both agree."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model import geometry

if TYPE_CHECKING:
    from cellrunner.model.cell import Gripper

#: a release waits for the jaws to open this fraction of their stroke before moving on
RELEASE_FRACTION = 0.5


def release_time_s(gripper: Gripper | None) -> float:
    """How long a release waits for the jaws to clear the part (s)."""
    return RELEASE_FRACTION * gripper.close_time if gripper is not None else 0.0


def close_time_s(gripper: Gripper | None, part_shape: geometry.Shape | None = None) -> float:
    """How long the jaws take to close on a part of ``part_shape`` (full stroke without)."""
    if gripper is None:
        return 0.0
    width = _width_m(part_shape)
    fraction = (
        1.0 if width is None else min(1.0, max(0.05, (gripper.stroke - width) / gripper.stroke))
    )
    return fraction * float(gripper.close_time)


def _width_m(shape: geometry.Shape | None) -> float | None:
    """The part's width across the jaws (the TCP's X axis, for an upright part)."""
    if isinstance(shape, geometry.Box):
        return float(min(shape.size_m[0], shape.size_m[1]))
    if isinstance(shape, (geometry.Cylinder, geometry.Sphere)):
        return 2.0 * float(shape.radius_m)
    return None
