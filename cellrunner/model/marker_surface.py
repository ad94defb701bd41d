"""Is a marker printed on the surface of what carries it? (SPEC section 13: a marker sits
on its part's or fixture's surface, Z out of the face.)

:func:`off_surface` measures a marker's pose in its carrier's own frame (the shape's
centre) against the shape: its centre on a face (a box's, a cylinder's end or side, a
sphere), its Z along that face's outward normal, its square inside the face. It returns
what is wrong as a clause (``None``: on the surface). Meshes are not measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Shape, Sphere

#: a marker's centre may lie this far off the face it is printed on (m): paper, a label
ON_FACE_M = 0.001
#: its Z may lean this far from the face's outward normal (deg)
NORMAL_DEG = 3.0


@dataclass(frozen=True)
class Face:
    """A flat face (or the tangent plane of a curved one) at ``point_m`` with outward
    ``normal``, the marker's square allowed within ``half_extent_m`` of its centre along
    the two face axes (None: not bounded, a curved side)."""

    name: str
    point_m: np.ndarray
    normal: np.ndarray
    half_extent_m: tuple[float, float] | None


def off_surface(shape: Shape, T_carrier_marker: np.ndarray, size_m: float) -> str | None:
    """What keeps a marker of edge ``size_m`` at ``T_carrier_marker`` (the carrier's own
    frame, m) off the carrier's surface, or None when it lies on it."""
    T = np.asarray(T_carrier_marker, float)
    p, z = T[:3, 3], T[:3, 2]
    face = nearest_face(shape, p)
    if face is None:
        return None
    gap_m = float(np.dot(p - face.point_m, face.normal))
    if abs(gap_m) > ON_FACE_M:
        where = "above" if gap_m > 0 else "inside"
        return f"its centre is {abs(gap_m) * 1000:.1f} mm {where} the {face.name}"
    lean_deg = math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(z, face.normal))))))
    if lean_deg > NORMAL_DEG:
        return (
            f"its Z (out of the printed face) is {lean_deg:.0f} deg from the {face.name}'s "
            "outward normal"
        )
    if face.half_extent_m is not None:
        corners = _corners(T, size_m)
        u, v = _face_axes(face.normal)
        for c in corners:
            du, dv = (
                abs(float(np.dot(c - face.point_m, u))),
                abs(float(np.dot(c - face.point_m, v))),
            )
            hu, hv = face.half_extent_m
            over_m = max(du - hu, dv - hv)
            if over_m > ON_FACE_M:
                return f"its square reaches {over_m * 1000:.1f} mm past the edge of the {face.name}"
    return None


def nearest_face(shape: Shape, p_m: np.ndarray) -> Face | None:
    """The face of ``shape`` (centred on its frame) nearest the point ``p_m``."""
    p = np.asarray(p_m, float)
    if isinstance(shape, Box):
        half = np.asarray(shape.size_m, float) / 2
        faces = []
        for axis, label in enumerate("xyz"):
            for sign in (1.0, -1.0):
                n = np.zeros(3)
                n[axis] = sign
                other = [half[k] for k in range(3) if k != axis]
                name = _box_face_name(axis, sign, label)
                faces.append(Face(name, n * half[axis], n, (other[0], other[1])))
        return min(faces, key=lambda f: _to_box_face_m(p, half, f))
    if isinstance(shape, Cylinder):
        r, h = shape.radius_m, shape.length_m / 2
        radial = np.array([p[0], p[1], 0.0])
        rho = float(np.linalg.norm(radial))
        caps = [
            Face("top end", np.array([0, 0, h]), np.array([0.0, 0, 1]), None),
            Face("bottom end", np.array([0, 0, -h]), np.array([0.0, 0, -1]), None),
        ]
        cap = min(caps, key=lambda f: abs(float(np.dot(p - f.point_m, f.normal))))
        if rho < 1e-9 or abs(abs(p[2]) - h) <= abs(rho - r):
            return Face(cap.name, cap.point_m, cap.normal, (r / math.sqrt(2), r / math.sqrt(2)))
        n = radial / rho
        return Face("side", np.array([n[0] * r, n[1] * r, p[2]]), n, None)
    if isinstance(shape, Sphere):
        norm = float(np.linalg.norm(p))
        n = p / norm if norm > 1e-9 else np.array([0.0, 0, 1])
        return Face("surface", n * shape.radius_m, n, None)
    return None


def _to_box_face_m(p: np.ndarray, half: np.ndarray, face: Face) -> float:
    """Distance (m) from ``p`` to the nearest point of a box's face (the rectangle, not
    its plane)."""
    q = np.clip(p, -half, half)
    k = int(np.argmax(np.abs(face.normal)))
    q[k] = face.point_m[k]
    return float(np.linalg.norm(p - q))


def _box_face_name(axis: int, sign: float, label: str) -> str:
    if axis == 2:
        return "top face" if sign > 0 else "bottom face"
    return f"{'+' if sign > 0 else '-'}{label} face"


def _corners(T: np.ndarray, size_m: float) -> np.ndarray:
    h = size_m / 2
    local = np.array([[-h, h, 0, 1], [h, h, 0, 1], [h, -h, 0, 1], [-h, -h, 0, 1]])
    return np.asarray((local @ T.T)[:, :3])


def _face_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit axes in a face: for a box face, the box's other two axes."""
    k = int(np.argmax(np.abs(normal)))
    axes = [np.eye(3)[i] for i in range(3) if i != k]
    return np.asarray(axes[0]), np.asarray(axes[1])
