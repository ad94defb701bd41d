"""Report pictures: an offscreen render of the cell, and the plots."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from cellrunner.model.geometry import Box, Placed, pose_matrix
from cellrunner.report.plots import plot_joints, plot_tcp_path
from cellrunner.sim.render import (
    CellRenderer,
    default_view,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _read_png(path):
    from matplotlib.image import imread

    return imread(path)


def test_render_produces_a_png_showing_the_cell(backend, tmp_path) -> None:
    if os.environ.get("MUJOCO_GL", "osmesa") not in ("osmesa", "egl"):
        pytest.skip("needs an offscreen GL backend")
    with CellRenderer(backend.world, width=480, height=360) as renderer:
        image = renderer.render()
        path = renderer.save_png(tmp_path / "cell.png", caption="home  t=0.000 s")
    assert image.shape == (360, 480, 3)
    assert image.std() > 20  # not a blank frame
    # the orange cube is in the picture
    orange = (
        (image[..., 0] > 200) & (image[..., 1] > 100) & (image[..., 1] < 170) & (image[..., 2] < 80)
    )
    assert orange.sum() > 20
    assert path.read_bytes()[:8] == PNG_MAGIC and path.stat().st_size > 10_000


def test_default_view_frames_robot_and_fixtures(backend) -> None:
    view = default_view(backend.world)
    assert 0.0 < view.lookat_m[0] < 0.6  # between the robot base and the table's far side
    assert 1.2 <= view.distance_m <= 6.0


def test_missing_gl_backend_is_a_clear_error_not_a_crash(tmp_path) -> None:
    code = (
        "from cellrunner.sim.mujoco_loader import enable_pictures\n"
        "enable_pictures()\n"  # pictures asked for, as dry-run --report does
        "from cellrunner.sim import demo\n"
        "from cellrunner.sim.world import SimWorld\n"
        "from cellrunner.sim.render import render_png, RenderUnavailable\n"
        "w = SimWorld(demo.demo_description()); w.build()\n"
        "try:\n"
        f"    render_png(w, {str(tmp_path / 'x.png')!r})\n"
        "except RenderUnavailable as e:\n"
        "    print('UNAVAILABLE', e)\n"
    )
    env = dict(os.environ, MUJOCO_GL="glfw", DISPLAY="", PYTHONPATH=os.getcwd())
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("UNAVAILABLE cannot render offscreen with MUJOCO_GL=glfw")
    assert "libosmesa6" in out.stdout


def test_joint_and_tcp_plots_are_written(tmp_path) -> None:
    t = np.linspace(0, 2, 200)
    q = np.stack([np.sin(t + j) for j in range(6)], axis=1)
    qd = np.gradient(q, t, axis=0)
    marks = [(0.0, 1, "move", "home"), (0.5, 2, "grip", "infeed"), (1.2, 3, "lift", "infeed")]
    p1 = plot_joints(tmp_path / "joints.png", t, q, qd, q + 0.01, marks, "demo")
    xyz = np.stack([0.4 + 0.1 * np.cos(t), 0.1 * np.sin(t), 1.0 + 0.05 * t], axis=1)
    table = Placed("table", Box((1.2, 0.8, 0.04)), pose_matrix((0.4, 0, 0.88)))
    p2 = plot_tcp_path(
        tmp_path / "tcp.png",
        xyz,
        [table],
        np.array([0.0, 0.0, 0.9]),
        [("2 grip", np.array([0.45, -0.35, 0.93]))],
        "demo",
    )
    for p in (p1, p2):
        assert p.read_bytes()[:8] == PNG_MAGIC
        assert _read_png(p).std() > 0.05
