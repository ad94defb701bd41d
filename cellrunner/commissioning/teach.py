"""Frames from the arm: the TCP pose where it stands, or a plane from three points
(origin, a point on +X, a point in the XY plane on the +Y side), as PolyScope's plane
feature builds it. Poses are world frame, m; a frame with a parent is written in it."""

from __future__ import annotations

import numpy as np

from cellrunner.errors import CellrunnerError
from cellrunner.model import geometry
from cellrunner.model.cell import Cell
from cellrunner.model.expand import frame_pose

#: three taught points closer than this cannot fix a frame's axes (m)
MIN_POINT_SPACING_M = 0.01
#: the XY-plane point must lie at least this far off the X axis, as an angle (deg)
MIN_PLANE_ANGLE_DEG = 10.0


class TeachError(CellrunnerError):
    """The taught points cannot define a frame (exit 1: teach again)."""


def frame_from_points(p_origin: np.ndarray, p_x: np.ndarray, p_plane: np.ndarray) -> np.ndarray:
    """T_world_frame with its origin at ``p_origin``, X towards ``p_x`` and ``p_plane`` in
    its XY plane on the +Y side (Z = X x Y, right-handed). Points in m."""
    p0, p1, p2 = (np.asarray(p, float) for p in (p_origin, p_x, p_plane))
    for name, a, b in (("+X point", p0, p1), ("plane point", p0, p2), ("plane point", p1, p2)):
        if np.linalg.norm(b - a) < MIN_POINT_SPACING_M:
            raise TeachError(
                f"the {name} is {np.linalg.norm(b - a) * 1000:.1f} mm from another point; "
                f"keep the points at least {MIN_POINT_SPACING_M * 1000:g} mm apart"
            )
    x = (p1 - p0) / np.linalg.norm(p1 - p0)
    v = p2 - p0
    angle = np.degrees(np.arccos(np.clip(abs(x @ v) / np.linalg.norm(v), 0.0, 1.0)))
    if angle < MIN_PLANE_ANGLE_DEG:
        raise TeachError(
            f"the plane point lies {angle:.1f} deg off the X axis; it must be at least "
            f"{MIN_PLANE_ANGLE_DEG:g} deg off it to fix the plane"
        )
    z = np.cross(x, v)
    z /= np.linalg.norm(z)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = p0
    return T


def in_parent(cell: Cell, frame: str, T_world_frame: np.ndarray) -> tuple[list[float], list[float]]:
    """``xyz`` (m) and ``rpy`` (deg) of a frame as the cell file writes it: relative to its
    parent when it has one."""
    existing = cell.frames.get(frame)
    parent = existing.parent if existing is not None else "world"
    T = (
        T_world_frame
        if parent == "world"
        else geometry.invert(frame_pose(cell, parent)) @ T_world_frame
    )
    return [float(v) for v in T[:3, 3]], list(geometry.rpy_deg_of(T[:3, :3]))
