"""What the MJCF writers share: the geom kinds (contype bits) and attribute formatting."""

from __future__ import annotations

import math
from typing import Any, TypedDict

import numpy as np

#: contype bits of the geom kinds
STATIC, ROBOT, PADS, PARTS, TOOL = 1, 2, 4, 8, 16
#: what a part's geom collides with
PART_HITS = STATIC | ROBOT | PADS | PARTS


def quat_of(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    m = np.asarray(R, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    n = math.sqrt(sum(v * v for v in q))
    a, b, c, d = (v / n for v in q)
    return (a, b, c, d)


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
