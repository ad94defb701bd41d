"""What the MJCF writers share: the geom kinds (contype bits) and attribute formatting."""

from __future__ import annotations

from typing import Any, TypedDict

import numpy as np

#: contype bits of the geom kinds
STATIC, ROBOT, PADS, PARTS, TOOL = 1, 2, 4, 8, 16
#: what a part's geom collides with
PART_HITS = STATIC | ROBOT | PADS | PARTS


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
