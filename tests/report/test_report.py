"""dry-run reports: views that see the work, overlays that land on the picture, labels
that do not overlap, and a report folder a person opens (index.html)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from cellrunner.model.geometry import Box, Placed, pose_matrix
from cellrunner.report.plots import free_offset, merged_labels
from cellrunner.report.views import choose_shots, occluders, project
from cellrunner.sim.mujoco_loader import load_mujoco
from cellrunner.sim.render import CameraView, CellRenderer
from tests.conftest import GL_BACKEND, ROOT

load_mujoco()

FENCES = [
    Placed("fence_front", Box((0.02, 1.6, 1.8)), pose_matrix((1.25, 0.0, 0.9))),
    Placed("fence_back", Box((0.02, 1.6, 1.8)), pose_matrix((-0.6, 0.0, 0.9))),
    Placed("fence_left", Box((1.85, 0.02, 1.8)), pose_matrix((0.325, 0.8, 0.9))),
    Placed("fence_right", Box((1.85, 0.02, 1.8)), pose_matrix((0.325, -0.8, 0.9))),
]
WORK = np.array(
    [[0.45, -0.35, 0.93], [0.45, -0.35, 1.03], [0.5, 0.1, 1.3], [0.4, 0.3, 1.03], [0.4, 0.3, 0.94]]
)


def test_a_fence_between_camera_and_work_is_found_and_only_it():
    # azimuth 135: the camera looks along (-1, 1, .), so it stands outside the +x/-y corner
    view = CameraView((0.4, 0.0, 1.1), 2.6, 135.0, -30.0)
    hidden = occluders(view, WORK, FENCES)
    assert set(hidden) == {"fence_right", "fence_front"}, hidden
    table = [Placed("table", Box((1.2, 0.8, 0.04)), pose_matrix((0.4, 0, 0.88)))]
    assert occluders(view, WORK, table) == {}  # what the work rests on does not hide it
    assert (
        occluders(CameraView((0.4, 0.0, 1.1), 2.6, 135.0, -89.9), WORK, FENCES) == {}
    )  # nothing above


def test_the_three_quarter_view_turns_to_the_side_that_hides_least():
    wall = [
        Placed("guard", Box((0.02, 3.0, 2.5)), pose_matrix((-0.7, 0.0, 1.25)))
    ]  # behind the base only
    top, side = choose_shots(WORK, np.array([0.0, 0.0, 0.9]), 0.85, wall, 45.0)
    assert top.view.elevation_deg < -89 and top.see_through == ()
    assert side.see_through == ()  # an azimuth exists from which the guard hides nothing
    assert occluders(side.view, WORK, wall) == {}
    assert occluders(
        CameraView(side.view.lookat_m, side.view.distance_m, 0.0, -30.0), WORK, wall
    )  # from behind it would


def test_step_labels_at_one_spot_are_merged_and_boxes_never_overlap():
    points = [
        ("3 descend", np.array([0.45, -0.35, 1.03])),
        ("6 approach", np.array([0.45, -0.35, 1.031])),
        ("4 grip", np.array([0.45, -0.35, 0.93])),
        ("5 lift", np.array([0.451, -0.35, 0.93])),
    ]
    assert [label for label, _ in merged_labels(points)] == [
        "3 descend, 6 approach",
        "4 grip, 5 lift",
    ]
    boxes: list = []
    for k in range(6):  # six labels at nearly one pixel
        free_offset((100.0, 100.0 + k), f"{k} approach pallet", boxes, 8)
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert a[2] < b[0] or a[0] > b[2] or a[3] < b[1] or a[1] > b[3], (a, b)


@pytest.mark.skipif(
    GL_BACKEND is None, reason="needs an offscreen GL backend (scripts/test installs libosmesa6)"
)
def test_projection_lands_on_the_rendered_part():
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.sim import demo

    backend = SimBackend(demo.demo_description())
    backend.connect()
    world = backend.world
    name = world.description.parts[0].name
    part = world.part_pose_world(name)[:3, 3]
    view = CameraView((0.4, 0.0, 1.0), 1.8, 135.0, -30.0)
    with CellRenderer(world, 400, 300) as renderer:
        image = renderer.render(view)
    ((u, v),) = project(part[None, :], view, 400, 300, float(world.model.vis.global_.fovy))
    r, g, b = (int(c) for c in image[round(v), round(u)])
    backend.close()
    assert r > 120 and r > 1.4 * g and b < 60, (
        u,
        v,
        r,
        g,
        b,
    )  # the orange block (not the brown table) is there


CELL = (
    (ROOT / "cells" / "demo_ur5e.yaml")
    .read_text()
    .replace(
        "  - {name: column, cylinder: {radius: 0.04, length: 0.40}, pose: {xyz: [0.50, 0.0, 1.10]}}\n",
        "  - {name: column, cylinder: {radius: 0.04, length: 0.40}, pose: {xyz: [0.50, 0.0, 1.10]}}\n"
        + "".join(
            f"  - {{name: {p.name}, box: {{size: {list(p.shape.size_m)}}}, pose: {{xyz: {p.T_parent_shape[:3, 3].tolist()}}}}}\n"
            for p in FENCES
        ),
    )
    .replace("tasks: {1: tasks/pick_place.yaml, 2: tasks/home.yaml}", "tasks: {1: tasks/t.yaml}")
)
TASK = (
    (ROOT / "tasks" / "pick_place.yaml")
    .read_text()
    .replace("max: 11", "max: 2")
    .replace("grid: [3, 4]", "grid: [1, 3]")
)


@pytest.mark.skipif(
    GL_BACKEND is None, reason="needs an offscreen GL backend (scripts/test installs libosmesa6)"
)
def test_report_of_a_fenced_cell_puts_everything_on_one_page(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell, task = tmp_path / "cells" / "fenced.yaml", tmp_path / "tasks" / "t.yaml"
    cell.write_text(CELL)
    task.write_text(TASK)
    report = tmp_path / "report"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "dry-run",
            str(cell),
            str(task),
            "-p",
            "slot=1",
            "--report",
            str(report),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
        env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin", "COLUMNS": "120"},
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert "pallet[slot=1]" in r.stderr  # the console keeps bracketed step names
    files = {p.name for p in report.iterdir()}
    assert {
        "index.html",
        "result.json",
        "top.png",
        "end.png",
        "tcp_path.png",
        "joints.png",
        "timelines.png",
        "slots.png",
        "slots.csv",
        "step04_grip.png",
        "step08_release.png",
    } <= files
    page = (report / "index.html").read_text()
    for name in files - {"index.html", "NO_PICTURES.txt"}:
        if name.endswith(".png"):
            assert f"src='{name}'" in page, name
    assert (
        "worst: slot=" in page and page.count("<tr") >= 1 + 10 + 1 + 3
    )  # steps header+rows, slots header+rows
    slots = (report / "slots.csv").read_text().splitlines()
    assert slots[0] == "slot,cycle_s,error" and [line.split(",")[0] for line in slots[1:]] == [
        "0",
        "1",
        "2",
    ]
    rows = json.loads((report / "result.json").read_text())["steps"]
    grip = next(row for row in rows if row["kind"] == "grip")
    assert grip["duration_s"] > 0.3  # its weighing after the lift is counted on the grip's row
    from matplotlib.image import imread

    end = imread(report / "end.png")
    assert end.std() > 0.05  # a picture, not a blank frame
