"""Renders that see the work: a top view and a 3/4 view framed on the TCP path and the
robot, fixtures standing between the camera and the work drawn transparent, the TCP
path and the steps drawn over the picture.

The camera is MuJoCo's free camera (look-at point, distance, azimuth, elevation; the
model's vertical field of view); :func:`project` maps world points (m) to its pixels the
way MuJoCo places that camera, so the overlay lands on the rendered scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.report.plots import (
    Box2D,
    figure,
    free_offset,
    merged_labels,
    save,
    shape_points_world,
)
from cellrunner.sim.render import CameraView, CellRenderer

if TYPE_CHECKING:
    from cellrunner.model.geometry import Placed
    from cellrunner.sim.world import SimWorld

#: azimuths tried for the 3/4 view (deg), the first wins ties: from the front left
AZIMUTHS_DEG = (135.0, 45.0, 225.0, 315.0, 90.0, 180.0, 270.0, 0.0)
#: the 3/4 view's elevation (deg, negative: from above) and the top view's
ELEVATION_DEG = -30.0
TOP_ELEVATION_DEG = -89.9
#: an occluding fixture is drawn with this opacity
SEE_THROUGH_ALPHA = 0.18


@dataclass(frozen=True)
class Shot:
    """A named camera view and the fixtures drawn see-through in it; ``ortho_height_m``:
    an orthographic view this many metres high (a plan, true to scale), else perspective."""

    name: str
    view: CameraView
    see_through: tuple[str, ...]
    ortho_height_m: float | None = None


def camera_axes(view: CameraView) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(head position, forward, up, right) of MuJoCo's free camera for ``view`` (world)."""
    az, el = math.radians(view.azimuth_deg), math.radians(view.elevation_deg)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    up = np.array([-math.sin(el) * math.cos(az), -math.sin(el) * math.sin(az), math.cos(el)])
    right = np.cross(forward, up)
    head = np.asarray(view.lookat_m, float) - view.distance_m * forward
    return head, forward, up, right


def project(
    points_m: np.ndarray,
    view: CameraView,
    width: int,
    height: int,
    fovy_deg: float,
    ortho_height_m: float | None = None,
) -> np.ndarray:
    """Pixel (u right, v down) of each world point; NaN behind the camera."""
    head, forward, up, right = camera_axes(view)
    d = np.atleast_2d(points_m) - head
    z = d @ forward
    if ortho_height_m is not None:
        scale = height / ortho_height_m
        u, v = width / 2 + scale * (d @ right), height / 2 - scale * (d @ up)
        out = np.column_stack([u, v])
        out[z <= 1e-6] = np.nan
        return out
    f = (height / 2) / math.tan(math.radians(fovy_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = width / 2 + f * (d @ right) / z
        v = height / 2 - f * (d @ up) / z
    out = np.column_stack([u, v])
    out[z <= 1e-6] = np.nan
    return out


def _aabb(placed: Placed) -> tuple[np.ndarray, np.ndarray]:
    pts = shape_points_world(placed)
    return pts.min(axis=0), pts.max(axis=0)


def _segment_hits_box(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Does the segment a -> b pass through the box [lo, hi] (slab test)?"""
    d = b - a
    t0, t1 = 0.0, 1.0
    for i in range(3):
        if abs(d[i]) < 1e-12:
            if not lo[i] <= a[i] <= hi[i]:
                return False
            continue
        ta, tb = (lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if t0 > t1:
            return False
    return True


def occluders(
    view: CameraView, work_m: np.ndarray, fixtures: list[Placed], stop_short_m: float = 0.03
) -> dict[str, int]:
    """Fixtures between the camera and the work points: name -> how many points each
    hides (the segment to a point stops ``stop_short_m`` before it, so the surface a
    part rests on does not count)."""
    head = camera_axes(view)[0]
    hidden: dict[str, int] = {}
    boxes = [(p.name, *_aabb(p)) for p in fixtures]
    for p in work_m:
        direction = p - head
        length = float(np.linalg.norm(direction))
        end = head + direction * max(0.0, (length - stop_short_m) / length)
        for name, lo, hi in boxes:
            if _segment_hits_box(head, end, lo, hi):
                hidden[name] = hidden.get(name, 0) + 1
    return hidden


def choose_shots(
    work_m: np.ndarray,
    base_m: np.ndarray,
    reach_m: float,
    fixtures: list[Placed],
    fovy_deg: float,
) -> list[Shot]:
    """The top view and the 3/4 view (the azimuth that hides the fewest work points),
    both framed on the work and the robot's base."""
    pts = np.vstack([work_m, base_m[None, :], base_m[None, :] + [0, 0, 0.6 * reach_m]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    tan_half = math.tan(math.radians(fovy_deg) / 2)
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.3)
    fit_m = radius / tan_half * 1.05
    half_m = (
        max(float(hi[0] - lo[0]) * 0.75, float(hi[1] - lo[1])) / 2 + 0.1
    )  # 4:3 picture, 10 cm margins
    # perspective: the lowest work fits the picture, higher work looks a little larger
    top = CameraView(
        (centre[0], centre[1], float(lo[2])),
        half_m / tan_half + float(hi[2] - lo[2]),
        90.0,
        TOP_ELEVATION_DEG,
    )
    sample = work_m[:: max(1, len(work_m) // 80)]
    best: tuple[int, CameraView, dict[str, int]] | None = None
    for az in AZIMUTHS_DEG:
        view = CameraView(tuple(centre), fit_m, az, ELEVATION_DEG)
        hidden = occluders(view, sample, fixtures)
        score = sum(hidden.values())
        if best is None or score < best[0]:
            best = (score, view, hidden)
    assert best is not None  # there are azimuths to try
    _, side, hidden = best
    top_hidden = occluders(top, sample, fixtures)
    return [
        Shot("top", top, tuple(sorted(top_hidden))),
        Shot("three_quarter", side, tuple(sorted(hidden))),
    ]


def render_shot(
    sim_world: SimWorld,
    shot: Shot,
    path: Path,
    tcp_m: np.ndarray,
    step_points: list[tuple[str, np.ndarray]],
    caption: str,
    width: int = 1000,
    height: int = 750,
) -> Path:
    """Render ``shot`` of the scene as it stands, occluders see-through, with the TCP path
    and step labels drawn over it; writes a PNG."""
    model = sim_world.model
    changed = []
    for name in shot.see_through:
        g = _geom_id(model, f"fixture:{name}")
        if g is None:
            continue
        changed.append((g, int(model.geom_matid[g]), model.geom_rgba[g].copy()))
        model.geom_matid[g] = -1
        model.geom_rgba[g] = (0.78, 0.62, 0.42, SEE_THROUGH_ALPHA)
    fovy = float(model.vis.global_.fovy)
    if shot.ortho_height_m is not None:
        model.vis.global_.orthographic, model.vis.global_.fovy = 1, shot.ortho_height_m
    try:
        with CellRenderer(sim_world, width, height) as renderer:
            image = renderer.render(shot.view)
    finally:
        model.vis.global_.orthographic, model.vis.global_.fovy = 0, fovy
        for g, matid, rgba in changed:
            model.geom_matid[g] = matid
            model.geom_rgba[g] = rgba
    fig = figure(width / 100, height / 100 + 0.4)
    ax = fig.add_axes((0, 0, 1, height / (height + 40)))
    ax.imshow(image)
    uv = project(np.asarray(tcp_m, float), shot.view, width, height, fovy, shot.ortho_height_m)
    ax.plot(uv[:, 0], uv[:, 1], color="#d62728", lw=1.6, alpha=0.85)
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    boxes: list[Box2D] = []
    for label, p in merged_labels(step_points):
        ((u, v),) = project(
            np.asarray(p, float)[None, :], shot.view, width, height, fovy, shot.ortho_height_m
        )
        if not (0 <= u < width and 0 <= v < height):
            continue
        ax.scatter([u], [v], s=14, color="black", zorder=3)
        offset = free_offset(ax.transData.transform((u, v)), label, boxes, 8)
        ax.annotate(
            label,
            (u, v),
            xytext=offset,
            textcoords="offset pixels",
            fontsize=8,
            color="black",
            zorder=4,
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "alpha": 0.8, "lw": 0},
            arrowprops={"arrowstyle": "-", "color": "#555555", "lw": 0.6},
        )
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_axis_off()
    see = f"; see-through: {', '.join(shot.see_through)}" if shot.see_through else ""
    fig.text(0.01, 0.995, f"{caption}{see}", va="top", ha="left", fontsize=10, family="monospace")
    return save(fig, path)


def _geom_id(model: Any, name: str) -> int | None:  # a MuJoCo MjModel
    for g in range(model.ngeom):
        if model.geom(g).name == name:
            return g
    return None
