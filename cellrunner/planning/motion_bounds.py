"""The maths behind conservative motion checking (see :mod:`.collision`'s docstring):
points and spheres that bound an object, how far an object can be from a joint axis in any
configuration, and the order of the coarse probes along a segment. (How far along a segment
a pair's margin proves it clear is computed inline in :meth:`.CollisionModel.check_motion`.)
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.planning.coal_shapes import local_aabb

if TYPE_CHECKING:
    import coal
    import pinocchio as pin


def support_points(
    geometry: coal.CollisionGeometry, T_parent_shape: np.ndarray
) -> tuple[np.ndarray, float]:
    """Points (n x 3, parent frame) and a pad (m) such that the shape lies within ``pad``
    of their convex hull: capsule and cylinder axis ends + radius, sphere centre + radius,
    box corners, else the corners of the local AABB. Any convex function of the point
    (a distance from a point or an axis) is largest over the shape at one of these points,
    plus the pad."""
    import coal

    if isinstance(geometry, (coal.Capsule, coal.Cylinder)):
        h = float(geometry.halfLength)
        local, pad = np.array([[0.0, 0.0, -h], [0.0, 0.0, h]]), float(geometry.radius)
    elif isinstance(geometry, coal.Sphere):
        local, pad = np.zeros((1, 3)), float(geometry.radius)
    else:
        lo, hi = local_aabb(geometry)
        local = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        pad = 0.0
    T = np.asarray(T_parent_shape, float)
    return local @ T[:3, :3].T + T[:3, 3], pad


def cover_spheres(
    geometry: coal.CollisionGeometry, T_parent_shape: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Spheres (centres n x 3 in the parent frame, radii n) whose union contains the shape:
    a capsule or cylinder as balls along its axis (spacing at most its radius), anything
    else as the ball around its local AABB."""
    import coal

    T = np.asarray(T_parent_shape, float)
    if isinstance(geometry, (coal.Capsule, coal.Cylinder)):
        # balls centred on the axis every `step` (at most the diameter), ends included:
        # a point at most r from the axis and step / 2 along it from a centre is within
        # hypot(r, step / 2); a capsule's end caps lie within r of the end centres
        h, r = float(geometry.halfLength), float(geometry.radius)
        n = max(1, math.ceil(h / max(r, 1e-3)))
        step = 2 * h / n
        z = -h + step * np.arange(n + 1)
        local = np.column_stack([np.zeros(n + 1), np.zeros(n + 1), z])
        radius = np.full(n + 1, math.hypot(r, step / 2))
    elif isinstance(geometry, coal.Sphere):
        local, radius = np.zeros((1, 3)), np.array([float(geometry.radius)])
    else:
        lo, hi = local_aabb(geometry)
        local, radius = ((lo + hi) / 2)[None, :], np.array([float(np.linalg.norm(hi - lo)) / 2])
    return local @ T[:3, :3].T + T[:3, 3], radius


#: :func:`polytope_cover_spheres` of the polytopes seen (the arm's parts: every collision
#: scene of a cell, one per carried part and contact, covers the same links)
_COVERS: dict[tuple[bytes, bytes, float], tuple[np.ndarray, np.ndarray]] = {}
_COVERS_MAX = 1024


def polytope_cover_spheres(
    vertices: np.ndarray, faces: np.ndarray, width_m: float = 0.06
) -> tuple[np.ndarray, np.ndarray]:
    """Spheres whose union contains the convex polytope (``vertices``, triangle ``faces``):
    the polytope cut into slabs along its longest axis, each slab's ball around the corners
    of the polytope's part in it (its vertices there and its edges' crossings of the slab's
    planes; the part is the hull of those, and a ball is convex). Kept per polytope; the
    arrays returned are shared (read only)."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces, int)
    key = (v.tobytes(), f.tobytes(), float(width_m))
    found = _COVERS.get(key)
    if found is None:
        found = _polytope_cover_spheres(v, f, width_m)
        for array in found:
            array.flags.writeable = False
        if len(_COVERS) >= _COVERS_MAX:
            _COVERS.pop(next(iter(_COVERS)))
        _COVERS[key] = found
    return found


def _polytope_cover_spheres(
    v: np.ndarray, f: np.ndarray, width_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`polytope_cover_spheres`, computed."""
    axis = np.linalg.svd(v - v.mean(axis=0), full_matrices=False)[2][0]
    s = v @ axis
    n = max(1, math.ceil((s.max() - s.min()) / width_m))
    cuts = np.linspace(s.min(), s.max(), n + 1)
    edges = np.unique(
        np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0
    )
    a, b = edges[:, 0], edges[:, 1]
    centres, radii = [], []
    for lo, hi in itertools.pairwise(cuts):
        corners = [v[(s >= lo) & (s <= hi)]]
        for plane in (lo, hi):
            cross = (s[a] - plane) * (s[b] - plane) < 0
            t = (plane - s[a][cross]) / (s[b][cross] - s[a][cross])
            corners.append(v[a][cross] + t[:, None] * (v[b][cross] - v[a][cross]))
        pts = np.concatenate(corners)
        if not len(pts):
            continue
        centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        centres.append(centre)
        radii.append(float(np.linalg.norm(pts - centre, axis=1).max()) + 1e-9)
    return np.array(centres), np.array(radii)


def joint_reach(model: pin.Model, body: int, points: np.ndarray, pad: float) -> np.ndarray:
    """R[j] (j = 1..6, as index j - 1): a bound, valid in every configuration, on the
    distance from joint j's axis of any point of an object carried by joint ``body``
    (given by its support ``points`` in joint ``body``'s frame and ``pad``).

    The point is o_j + t_(j+1) + ... + t_body + (p - o_body), each offset t_m fixed in
    joint m-1's frame. Its distance from the axis is at most the sum of the offsets'
    components across the axis. While the axes of joints j..m-1 are all parallel (as for
    the UR shoulder, elbow and wrist 1), t_m's component across axis j is exactly its
    x-y part in joint m-1's frame; past the first axis that is not parallel, the whole
    length |t_m| counts. Zero for the joints after ``body``."""
    reach = np.zeros(6)
    across_pts = float(np.hypot(points[:, 0], points[:, 1]).max()) + pad
    whole_pts = float(np.linalg.norm(points, axis=1).max()) + pad
    for j in range(1, body + 1):
        parallel, total = True, 0.0
        for m in range(j + 1, body + 1):
            t = model.jointPlacements[m].translation
            total += math.hypot(t[0], t[1]) if parallel else float(np.linalg.norm(t))
            parallel = parallel and abs(model.jointPlacements[m].rotation[2, 2]) > 1.0 - 1e-12
        reach[j - 1] = total + (across_pts if parallel else whole_pts)
    return reach


def bisection_order(n: int) -> list[float]:
    """Interior fractions k/n, k = 1..n-1, coarse to fine (midpoint first)."""
    if n < 2:
        return []
    order, seen, step = [], set(), n
    while step > 1:
        step = max(1, step // 2)
        for k in range(step, n, step):
            if k not in seen:
                seen.add(k)
                order.append(k / n)
    return order
