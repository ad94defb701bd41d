"""ArUco markers (SPEC sections 12 and 13): the marker an ``align`` looks at, and the
markers a part or fixture carries (``markers:``, printed on its surface).

A marker's frame: origin at the centre of its black square, Z out of the printed face, X
and Y along its edges (OpenCV's ArUco convention: corner 0 at (-size/2, +size/2)).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from cellrunner.model.base import Pose, Strict
from cellrunner.model.camera import Dictionary
from cellrunner.model.units import PositiveLength

MarkerId = Annotated[int, Field(ge=0, le=999)]


class Marker(Strict):
    """An ArUco marker (OpenCV's predefined dictionaries)."""

    dictionary: Dictionary = "DICT_4X4_50"
    """ArUco dictionary. Example: `DICT_4X4_50`"""
    id: MarkerId
    """Marker id in its dictionary. Example: `7`"""
    size: PositiveLength
    """Edge of the black square, m. Example: `0.03`"""
    pose: Pose = Field(default_factory=Pose)
    """Where the marker sits in the target frame of the next step (its centre, Z out of the printed face), m and deg. Example: `{xyz: [0, 0, -0.02], rpy: [180, 0, 0]}`"""


class PrintedMarker(Marker):
    """A marker printed on a part or fixture (``markers:`` of SPEC section 13)."""

    pose: Pose = Field(default_factory=Pose)
    """Where the marker sits in the part's or fixture's own frame (the centre of its shape; a part upright as it lies at its frame), on its surface with Z out of the face, m and deg. Example: `{xyz: [0, 0, 0.025]}`"""
