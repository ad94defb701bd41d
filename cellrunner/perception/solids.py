"""Convex solids that say which points lie within a distance of them.

Every solid is convex and placed in some frame; :meth:`Solid.near` takes points already in
the solid's own frame. A box grows by ``pad`` along each face normal (its corners by up
to sqrt(3) x ``pad``), a hull by ``pad`` along each face's normal: a superset of the true
``pad`` neighbourhood, never a subset, which is what a filter of known things and a check
for obstacles both need (neither may miss a point within ``pad``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Mesh, Shape, Sphere


@dataclass(frozen=True, eq=False)
class Solid:
    """A convex solid in its own frame: ``kind`` box (``size`` the half extents),
    cylinder (``size`` = radius, half length, 0; axis Z), sphere (``size`` = radius, 0, 0)
    or hull (``planes``: unit outward normals and offsets, n x 4, inside where
    n.p <= d). ``radius_m`` bounds its points' distance from the origin."""

    kind: str
    size: tuple[float, float, float]
    radius_m: float
    planes: np.ndarray | None = None

    def near(self, p: np.ndarray, pad_m: float) -> np.ndarray:
        """Which points ``p`` (N x 3, this solid's frame) lie within ``pad_m`` of it (bool N)."""
        if self.kind == "box":
            h = np.asarray(self.size) + pad_m
            return np.asarray(np.all(np.abs(p) <= h, axis=1))
        if self.kind == "cylinder":
            r, half, _ = self.size
            return np.asarray(
                (np.abs(p[:, 2]) <= half + pad_m)
                & (p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1] <= (r + pad_m) ** 2)
            )
        if self.kind == "sphere":
            return np.asarray(np.einsum("ij,ij->i", p, p) <= (self.size[0] + pad_m) ** 2)
        assert self.planes is not None  # a hull has its planes
        n, d = self.planes[:, :3], self.planes[:, 3]
        return np.asarray(np.all(p @ n.T <= d + pad_m, axis=1))


def solid_of(shape: Shape) -> Solid:
    """The solid of a cell shape; a mesh becomes its convex hull (a superset of it)."""
    if isinstance(shape, Box):
        h = tuple(s / 2 for s in shape.size_m)
        return Solid("box", (h[0], h[1], h[2]), float(np.linalg.norm(h)))
    if isinstance(shape, Cylinder):
        half = shape.length_m / 2
        return Solid("cylinder", (shape.radius_m, half, 0.0), float(np.hypot(shape.radius_m, half)))
    if isinstance(shape, Sphere):
        return Solid("sphere", (shape.radius_m, 0.0, 0.0), shape.radius_m)
    if isinstance(shape, Mesh):
        from cellrunner.planning.stl import read_stl

        vertices, _ = read_stl(shape.path)
        return hull_of(np.asarray(vertices, float) * shape.scale)
    raise TypeError(f"unknown shape {shape!r}")


def hull_of(vertices_m: np.ndarray) -> Solid:
    """The convex hull of points (n x 3) as a solid: the planes of Qhull's facets, the
    same hull the twin (MuJoCo) builds from a mesh's vertices.

    Never planes taken from triangles of a hull's surface (the arm's parts carry such
    triangles, for drawing): Qhull splits a facet into triangles, some of them slivers
    whose corners nearly coincide, and a sliver's own normal points anywhere. On the
    UR10's forearm one such plane cut 139 mm off the part, and the watch took the
    forearm it saw for an obstacle (docs/check-truth.md)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(np.asarray(vertices_m, float))
    planes = np.array(hull.equations, float)  # n.p + c <= 0 inside, n a unit vector
    planes[:, 3] = -planes[:, 3]
    # a facet split into triangles repeats its plane: keep each plane once
    _, first = np.unique(np.round(planes, 12), axis=0, return_index=True)
    planes = planes[np.sort(first)]
    radius = float(np.linalg.norm(vertices_m, axis=1).max())
    return Solid("hull", (0.0, 0.0, 0.0), radius, planes)


@dataclass(frozen=True, eq=False)
class PlacedSolid:
    """A solid at ``T_body_solid`` on body ``body`` (0..6: the arm's joints as
    :meth:`~cellrunner.planning.collision.CollisionModel.joint_frames` numbers them, 0 =
    the base; -1: the world), named for messages."""

    name: str
    solid: Solid
    body: int
    T_body_solid: np.ndarray


def near_any(
    solids: list[tuple[Solid, np.ndarray]], points_m: np.ndarray, pad_m: float
) -> np.ndarray:
    """Which world points (N x 3) lie within ``pad_m`` of any of the solids, each given with
    its world pose ``T_world_solid`` (bool N); only points inside a solid's bounding sphere
    (grown by the pad) are tested against it."""
    hit = np.zeros(len(points_m), bool)
    for solid, T in solids:
        centre = T[:3, 3]
        d = points_m - centre
        candidates = np.flatnonzero(
            (~hit) & (np.einsum("ij,ij->i", d, d) <= (solid.radius_m + pad_m) ** 2)
        )
        if not len(candidates):
            continue
        local = d[candidates] @ T[:3, :3]
        hit[candidates[solid.near(local, pad_m)]] = True
    return hit
