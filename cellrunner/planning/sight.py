"""Lines of sight: does anything stand between a lens and the points it must see?
Points are sampled along each line and tested against simple shapes (box, cylinder,
sphere; a mesh is not tested), each placed in the world."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Shape, Sphere


def first_in_the_way(
    eye_m: np.ndarray,
    targets_m: np.ndarray,
    bodies: Sequence[tuple[str, Shape, np.ndarray]],
    samples: int,
    end_m: float,
) -> tuple[str, float] | None:
    """The first body (its name, and how far from ``eye_m`` along a line, m) that one of
    the straight lines from ``eye_m`` to ``targets_m`` (N x 3, world) passes through,
    leaving out the last ``end_m`` before each target; None when every line is clear.
    ``bodies``: (name, shape, T_world_shape)."""
    eye = np.asarray(eye_m, float)
    best: tuple[str, float] | None = None
    for target in np.asarray(targets_m, float).reshape(-1, 3):
        length = float(np.linalg.norm(target - eye))
        if length <= end_m:
            continue
        t = np.linspace(0.0, (length - end_m) / length, samples)
        points = eye + t[:, None] * (target - eye)
        for name, shape, T in bodies:
            inside = inside_shape(shape, T, points)
            if inside.any():
                d = float(t[int(np.argmax(inside))] * length)
                if best is None or d < best[1]:
                    best = (name, d)
    return best


def inside_shape(shape: Shape, T_world_shape: np.ndarray, points_m: np.ndarray) -> np.ndarray:
    """Which of the points (N x 3, world) lie inside ``shape`` at ``T_world_shape``."""
    T = np.asarray(T_world_shape, float)
    local = (np.asarray(points_m, float) - T[:3, 3]) @ T[:3, :3]
    if isinstance(shape, Box):
        return np.asarray(np.all(np.abs(local) <= np.asarray(shape.size_m) / 2, axis=1))
    if isinstance(shape, Cylinder):
        radial = np.hypot(local[:, 0], local[:, 1])
        return np.asarray((radial <= shape.radius_m) & (np.abs(local[:, 2]) <= shape.length_m / 2))
    if isinstance(shape, Sphere):
        return np.asarray(np.linalg.norm(local, axis=1) <= shape.radius_m)
    return np.zeros(len(local), bool)
