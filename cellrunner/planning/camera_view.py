"""What a camera sees, as ``check`` proves it (SPEC sections 12 and 13): points projected
through the camera's pinhole and lens (OpenCV's model: Z out of the lens, X right, Y down;
radial k1 k2 k3 and tangential p1 p2 distortion), each inside the picture with a margin
and in front of the lens (within the depth range of a depth camera).

:func:`unseen` says which points a camera misses and why, as one clause per cause;
:func:`seen_mask` which of many points it sees (the samples of a watched zone,
:func:`zone_samples_m`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cellrunner.model.camera import Camera

#: a point the camera must see lies at least this share of the picture's width and
#: height inside its edges (a marker's corner, a zone's corner): a detector needs its
#: whole square with a quiet border, a map its zone with room for the camera's slip
EDGE_MARGIN = 0.05
#: a point nearer the lens than this (m) along its Z is not seen
NEAREST_M = 0.02


@dataclass(frozen=True)
class View:
    """Points seen through a camera: pixel coordinates (N x 2), depth along the camera's
    Z (N, m)."""

    uv_px: np.ndarray
    depth_m: np.ndarray


def project(camera: Camera, T_world_camera: np.ndarray, points_world_m: np.ndarray) -> View:
    """The points (N x 3, world, m) as ``camera`` at ``T_world_camera`` sees them."""
    P = np.asarray(points_world_m, float).reshape(-1, 3)
    T_camera_world = np.linalg.inv(np.asarray(T_world_camera, float))
    p = P @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
    z = p[:, 2]
    safe = np.where(np.abs(z) < 1e-9, 1e-9, z)
    x, y = p[:, 0] / safe, p[:, 1] / safe
    d = [*camera.intrinsics.distortion, 0.0, 0.0, 0.0, 0.0, 0.0][:5]
    k1, k2, p1, p2, k3 = d
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    i = camera.intrinsics
    uv = np.stack([i.fx * xd + i.cx, i.fy * yd + i.cy], axis=1)
    return View(uv, z)


def unseen(
    camera: Camera,
    T_world_camera: np.ndarray,
    points_world_m: np.ndarray,
    depth_range_m: tuple[float, float] | None = None,
) -> list[str]:
    """Why ``camera`` misses some of the points: one clause per cause (behind the lens,
    out of the picture or within its margin, out of the depth range); [] when it sees
    them all."""
    view = project(camera, T_world_camera, points_world_m)
    w, h = camera.image_size
    mu, mv = EDGE_MARGIN * w, EDGE_MARGIN * h
    clauses = []
    behind = view.depth_m < NEAREST_M
    if behind.any():
        clauses.append(
            f"{int(behind.sum())} of {len(behind)} corners lie behind the lens "
            f"(nearest {float(view.depth_m.min()) * 1000:+.0f} mm along its Z)"
        )
    front = ~behind
    u, v = view.uv_px[:, 0], view.uv_px[:, 1]
    out = front & ((u < mu) | (u > w - mu) | (v < mv) | (v > h - mv))
    if out.any():
        k = int(np.argmax(np.maximum.reduce([mu - u, u - (w - mu), mv - v, v - (h - mv)]) * out))
        clauses.append(
            f"{int(out.sum())} of {len(out)} corners fall outside the picture's "
            f"{w} x {h} px less a {EDGE_MARGIN:.0%} margin (one at "
            f"({u[k]:.0f}, {v[k]:.0f}) px)"
        )
    if depth_range_m is not None:
        near, far = depth_range_m
        beyond = front & ((view.depth_m < near) | (view.depth_m > far))
        if beyond.any():
            clauses.append(
                f"{int(beyond.sum())} corners lie outside the depth range "
                f"[{near:g}, {far:g}] m (from {float(view.depth_m[front].min()):.2f} to "
                f"{float(view.depth_m[front].max()):.2f} m)"
            )
    return clauses


def seen_mask(
    camera: Camera,
    T_world_camera: np.ndarray,
    points_world_m: np.ndarray,
    depth_range_m: tuple[float, float] | None = None,
) -> np.ndarray:
    """Which of the points (N x 3, world, m) ``camera`` sees (in front, inside the
    picture, within the depth range), as a boolean array."""
    view = project(camera, T_world_camera, points_world_m)
    w, h = camera.image_size
    u, v, z = view.uv_px[:, 0], view.uv_px[:, 1], view.depth_m
    near, far = depth_range_m if depth_range_m is not None else (NEAREST_M, np.inf)
    return np.asarray(
        (z >= max(near, NEAREST_M)) & (z <= far) & (u >= 0) & (u <= w) & (v >= 0) & (v <= h)
    )


def zone_samples_m(
    size_m: tuple[float, float, float], T_world_zone: np.ndarray, per_axis: int = 10
) -> np.ndarray:
    """Points (per_axis^3 x 3, world, m) at the centres of a regular grid of cells filling
    a box of ``size_m`` centred on ``T_world_zone``: each stands for an equal share of
    its volume."""
    n = per_axis
    ticks = np.linspace(-0.5 + 0.5 / n, 0.5 - 0.5 / n, n)
    grid = np.stack(np.meshgrid(ticks, ticks, ticks, indexing="ij"), -1).reshape(-1, 3)
    local = grid * np.asarray(size_m, float)
    T = np.asarray(T_world_zone, float)
    return np.asarray(local @ T[:3, :3].T + T[:3, 3])


def zone_corners_m(size_m: tuple[float, float, float], T_world_zone: np.ndarray) -> np.ndarray:
    """The eight corners (8 x 3, world, m) of a box of ``size_m`` centred on
    ``T_world_zone``."""
    half = np.asarray(size_m, float) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    local = signs * half
    T = np.asarray(T_world_zone, float)
    return np.asarray(local @ T[:3, :3].T + T[:3, 3])
