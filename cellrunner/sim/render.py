"""Offscreen MuJoCo renders of the cell (the report's plots are in :mod:`cellrunner.report.plots`).

Offscreen rendering needs an OpenGL backend, chosen by
:func:`~cellrunner.sim.mujoco_loader.enable_pictures` before MuJoCo is imported (EGL, then
OSMesa: Debian's ``libosmesa6``, software, works anywhere). Without one,
:class:`CellRenderer` raises :class:`RenderUnavailable` with that advice instead of
crashing.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cellrunner.errors import CellrunnerError
from cellrunner.sim.mujoco_loader import GL_ADVICE, gl_backend, load_mujoco, no_gl_reason


class RenderUnavailable(CellrunnerError):
    """Offscreen rendering is not possible on this machine; the message says what to do."""


@dataclass(frozen=True)
class CameraView:
    """A free camera: looks at ``lookat_m`` (world) from ``distance_m`` away, turned
    ``azimuth_deg`` about world Z and ``elevation_deg`` (negative: from above)."""

    lookat_m: tuple[float, float, float]
    distance_m: float
    azimuth_deg: float = 135.0
    elevation_deg: float = -28.0


def default_view(world: Any) -> CameraView:
    """A 3/4 view from the front left and above, framing the robot, fixtures and parts."""
    model, data = world.model, world.data
    base = world.description.T_world_base[:3, 3]
    reach = world.description.spec.reach_m
    points = [base + (-0.3 * reach, -0.3 * reach, 0), base + (0.3 * reach, 0.3 * reach, reach)]
    for g in range(model.ngeom):
        if model.geom(g).name.startswith(("fixture:", "part:")):
            centre = data.geom_xpos[g]
            if np.linalg.norm(centre[:2] - base[:2]) < 2.0 * reach:  # skip far-away walls
                points.append(centre)
    pts = np.array(points)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    centre[2] = base[2] + 0.2 * reach
    extent = float(np.linalg.norm(hi - lo))
    return CameraView(
        (float(centre[0]), float(centre[1]), float(centre[2])),
        float(np.clip(1.5 * extent, 1.2, 6.0)),
    )


class CellRenderer:
    """Renders a :class:`~cellrunner.sim.world.SimWorld` offscreen.

    Holds one GL context; ``close()`` it (or use it as a context manager)."""

    def __init__(self, world: Any, width: int = 1024, height: int = 768) -> None:
        self.world = world
        self.width, self.height = width, height
        self._renderer: Any = None

    def __enter__(self) -> CellRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open(self) -> Any:
        if self._renderer is None:
            mujoco = load_mujoco()
            backend = gl_backend()
            if backend is None:
                raise RenderUnavailable(f"{no_gl_reason()} ({GL_ADVICE} gives one)")
            try:
                self._renderer = mujoco.Renderer(self.world.model, self.height, self.width)
            except Exception as exc:  # GL backends fail with many exception types
                raise RenderUnavailable(
                    f"cannot render offscreen with MUJOCO_GL={backend}: {exc} ({GL_ADVICE} gives "
                    "a software backend; MUJOCO_GL=egl needs a GPU or Mesa's EGL)"
                ) from exc
        return self._renderer

    def render(self, view: CameraView | None = None) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) of the cell now."""
        mujoco = load_mujoco()
        renderer = self._open()
        view = view or default_view(self.world)
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = view.lookat_m
        cam.distance = view.distance_m
        cam.azimuth = view.azimuth_deg
        cam.elevation = view.elevation_deg
        renderer.update_scene(self.world.data, camera=cam)
        return np.array(renderer.render())

    def save_png(self, path: str | Path, caption: str = "", view: CameraView | None = None) -> Path:
        """Render and write a PNG (with an optional caption line); returns the path."""
        image = self.render(view)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        figure = _figure(self.width / 100, self.height / 100 + (0.35 if caption else 0))
        ax = figure.add_axes((0, 0, 1, self.height / (self.height + (35 if caption else 0))))
        ax.imshow(image)
        ax.set_axis_off()
        if caption:
            figure.text(0.01, 0.995, caption, va="top", ha="left", fontsize=11, family="monospace")
        figure.savefig(path, dpi=100)
        return path

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def render_png(
    world: Any, path: str | Path, caption: str = "", width: int = 1024, height: int = 768
) -> Path:
    """One PNG of the cell now (opens and closes a GL context)."""
    with CellRenderer(world, width, height) as renderer:
        return renderer.save_png(path, caption)


def _figure(width_in: float, height_in: float) -> Any:
    from matplotlib.figure import Figure  # no pyplot: no global state, no display

    return Figure(figsize=(width_in, height_in), dpi=100)


__all__ = ["CameraView", "CellRenderer", "RenderUnavailable", "default_view", "render_png"]
