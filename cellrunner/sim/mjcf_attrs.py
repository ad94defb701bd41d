"""What the MJCF writers share: the geom kinds (contype bits) and attribute formatting."""

from __future__ import annotations

from typing import Any, TypedDict

import numpy as np

#: contype bits of the geom kinds
STATIC, ROBOT, PADS, PARTS, TOOL = 1, 2, 4, 8, 16
#: the contype bit of a press fit's fixtures (:mod:`.press_fits`): static, but a part
#: pressed into them stops touching them (it clears this bit of its conaffinity)
PRESS = 32
#: what a part's geom collides with
PART_HITS = STATIC | ROBOT | PADS | PARTS | PRESS


def geom_kind(contype: int, conaffinity: int) -> int:
    """The collision kind of a geom with these bits: its contype (0: it collides with
    nothing), a press fit's fixture being a fixture (its own bit only filters contacts)."""
    if not (contype or conaffinity):
        return 0
    return STATIC if contype == PRESS else int(contype)


class CollisionBits(TypedDict):
    """An MJCF geom's collision filter attributes."""

    contype: str
    conaffinity: str


def fixture_bits(press_fit: bool) -> CollisionBits:
    """A fixture geom's contype and conaffinity: static, or a press fit's fixture (its
    own bit, which a part in the fit clears to pass into it)."""
    if press_fit:
        return {"contype": str(PRESS), "conaffinity": str(ROBOT | PADS | TOOL)}
    return {"contype": str(STATIC), "conaffinity": str(ROBOT | PADS | PARTS)}


def quat_of(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = Rotation.from_matrix(np.asarray(R, dtype=float)).as_quat(scalar_first=True)
    return (float(w), float(x), float(y), float(z))


def fmt(values: Any) -> str:
    """Numbers as MJCF writes them: space separated, 9 significant digits."""
    return " ".join(f"{float(v):.9g}" for v in np.ravel(values))


class PoseAttrs(TypedDict):
    """An MJCF element's pose attributes."""

    pos: str
    quat: str


class ShapeAttrs(TypedDict, total=False):
    """An MJCF geom's shape attributes."""

    type: str
    size: str
    mesh: str


def pose_attrs(T: np.ndarray) -> PoseAttrs:
    """The ``pos`` and ``quat`` attributes of pose ``T``."""
    return {"pos": fmt(T[:3, 3]), "quat": fmt(quat_of(T[:3, :3]))}
