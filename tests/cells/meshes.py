"""Meshes written for tests: boxes as triangles, and STL files of them."""

from __future__ import annotations

import itertools
import struct

import numpy as np


def box_triangles(centre, size) -> list[np.ndarray]:
    """The 12 outward-wound triangles of a box."""
    c, h = np.asarray(centre), np.asarray(size) / 2
    out = []
    for axis, sign in itertools.product(range(3), (-1, 1)):
        u, v = [a for a in range(3) if a != axis]
        corners = []
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            p = c.copy()
            p[axis] += sign * h[axis]
            p[u] += su * h[u]
            p[v] += sv * h[v]
            corners.append(p)
        quad = (
            corners
            if np.dot(
                np.cross(corners[1] - corners[0], corners[2] - corners[0]), np.eye(3)[axis] * sign
            )
            > 0
            else corners[::-1]
        )
        out += [np.array([quad[0], quad[1], quad[2]]), np.array([quad[0], quad[2], quad[3]])]
    return out


def write_stl(path, triangles) -> None:
    data = bytearray(80) + struct.pack("<I", len(triangles))
    for t in triangles:
        data += struct.pack("<12fH", 0, 0, 0, *t.ravel(), 0)
    path.write_bytes(bytes(data))
