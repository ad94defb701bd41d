"""The cell's shapes as coal collision geometry, and the boxes and frames around them."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Mesh, Shape, Sphere, Voxels
from cellrunner.planning.mesh_hull import convexity
from cellrunner.planning.stl import read_stl

if TYPE_CHECKING:
    import coal


def make_coal_shape(shape: Shape) -> tuple[coal.CollisionGeometry, float]:
    """A coal geometry and its bounding-sphere radius about the shape origin (m)."""
    import coal

    if isinstance(shape, Box):
        x, y, z = shape.size_m
        return coal.Box(x, y, z), 0.5 * math.sqrt(x * x + y * y + z * z)
    if isinstance(shape, Cylinder):
        return coal.Cylinder(shape.radius_m, shape.length_m), math.hypot(
            shape.radius_m, shape.length_m / 2
        )
    if isinstance(shape, Sphere):
        return coal.Sphere(shape.radius_m), shape.radius_m
    if isinstance(shape, Voxels):  # the watched zone's map: an octree of the grown voxels
        points = shape.grown()
        tree = coal.makeOctree(np.ascontiguousarray(points, dtype=float), shape.voxel_m)
        return tree, float(np.linalg.norm(points, axis=1).max()) + shape.voxel_m
    if isinstance(shape, Mesh):
        vertices, triangles = read_stl(shape.path)
        vertices = vertices * shape.scale
        radius = float(np.linalg.norm(vertices, axis=1).max()) if len(vertices) else 0.0
        if len(triangles) and convexity(vertices[triangles]):  # as the twin collides it
            points = coal.StdVec_Vec3s()
            points.extend(list(vertices))
            return coal.Convex.convexHull(points, False, ""), radius
        model = coal.BVHModelOBBRSS()
        model.beginModel(len(triangles), len(vertices))
        model.addVertices(np.ascontiguousarray(vertices, dtype=float))
        model.addTriangles(np.ascontiguousarray(triangles, dtype=np.int64))
        model.endModel()
        return model, radius
    raise TypeError(f"unknown shape {shape!r}")


def local_aabb(geometry: coal.CollisionGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Corners (lo, hi) of a geometry's box in its own frame."""
    import coal

    if isinstance(geometry, coal.Box):
        hi = np.asarray(geometry.halfSide, float)
        return -hi, hi
    geometry.computeLocalAABB()
    return np.array(geometry.aabb_local.min_), np.array(geometry.aabb_local.max_)


def world_aabb(
    geometry: coal.CollisionGeometry, T_world_shape: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box in the world around ``geometry`` placed at ``T_world_shape``."""
    geometry.computeLocalAABB()
    box = geometry.aabb_local
    lo, hi = np.array(box.min_), np.array(box.max_)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    world = corners @ T_world_shape[:3, :3].T + T_world_shape[:3, 3]
    return world.min(axis=0), world.max(axis=0)


def segment_frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """A frame at the segment's midpoint with its z axis along p0 -> p1."""
    T = np.eye(4)
    T[:3, 3] = (p0 + p1) / 2
    d = p1 - p0
    n = np.linalg.norm(d)
    if n > 1e-12:
        z = d / n
        helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T
