"""Where the markers of a cell are (SPEC section 13: markers live on what carries them).

A part's markers are given in its own frame: upright at its frame (``at:``), centred
where a TCP at that frame grips it (:mod:`cellrunner.model.part_pose`; the gripper is
the tool mounted at the start); a fixture's in its shape's frame. An ``align`` names a
marker by id (looked up on the part at its target frame, then on the fixtures), or gives
one inline: a marker at that pose in the target frame, printed on the part at the
target. Both give the marker's pose in the target frame, which the align measures.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from cellrunner.model.frames import frame_pose
from cellrunner.model.marker import Marker, PrintedMarker
from cellrunner.model.part_pose import part_pose

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell, Part
    from cellrunner.model.geometry import Shape


@dataclass(frozen=True, eq=False)
class Carrier:
    """A part or fixture that carries markers: its shape and its own frame in the world
    (a part as it lies at its frame, nominally: without its twin-only ``offset``)."""

    kind: Literal["part", "fixture"]
    name: str
    shape: Shape
    T_world_carrier: np.ndarray
    markers: tuple[PrintedMarker, ...]

    @property
    def label(self) -> str:
        return f"{self.kind} {self.name!r}"


def part_carrier(cell: Cell, part: Part) -> Carrier:
    """``part`` as a carrier, at its frame."""
    shape = part.to_shape(Path)
    gripper = cell.tool.gripper if cell.tool is not None else None
    T = part_pose(frame_pose(cell, part.at), gripper, shape)
    return Carrier("part", part.name, shape, T, tuple(part.markers))


def carriers(cell: Cell) -> list[Carrier]:
    """Every part (at its frame) and fixture of the cell."""
    out = [part_carrier(cell, p) for p in cell.parts]
    out += [
        Carrier("fixture", f.name, f.to_shape(Path), f.matrix(), tuple(f.markers))
        for f in cell.fixtures
    ]
    return out


def part_at(cell: Cell, frame: str) -> Part | None:
    """The part that waits at ``frame`` (its ``at:``), if one does."""
    return next((p for p in cell.parts if p.at == frame), None)


def find_marker(cell: Cell, frame: str, marker_id: int) -> tuple[Carrier, PrintedMarker] | None:
    """The marker ``marker_id`` on the part at ``frame``, else on a fixture."""
    part = part_at(cell, frame)
    found = [part_carrier(cell, part)] if part is not None else []
    found += [c for c in carriers(cell) if c.kind == "fixture"]
    for carrier in found:
        for marker in carrier.markers:
            if marker.id == marker_id:
                return carrier, marker
    return None


def marker_in_frame(cell: Cell, frame: str, marker: int | Marker) -> Marker:
    """The align's marker with its pose in the target ``frame`` (an inline marker as
    written; an id resolved on its carrier). Raises KeyError for an unknown id (the
    references check refuses it first)."""
    if isinstance(marker, Marker):
        return marker
    hit = find_marker(cell, frame, marker)
    if hit is None:
        raise KeyError(marker)
    carrier, printed = hit
    T_frame_marker = (
        np.linalg.inv(frame_pose(cell, frame)) @ carrier.T_world_carrier @ printed.pose.matrix()
    )
    from cellrunner.model.base import Pose
    from cellrunner.model.geometry import rpy_deg_of

    pose = Pose(xyz=list(T_frame_marker[:3, 3]), rpy=list(rpy_deg_of(T_frame_marker[:3, :3])))
    return Marker(dictionary=printed.dictionary, id=printed.id, size=printed.size, pose=pose)


def inline_on_part(cell: Cell, frame: str, marker: Marker) -> tuple[Carrier, np.ndarray] | None:
    """An inline align marker on the part at ``frame``: the part as a carrier and the
    marker's pose in the part's own frame (None: no part waits there)."""
    part = part_at(cell, frame)
    if part is None:
        return None
    carrier = part_carrier(cell, part)
    T = np.linalg.inv(carrier.T_world_carrier) @ frame_pose(cell, frame) @ marker.pose.matrix()
    return carrier, np.asarray(T)
