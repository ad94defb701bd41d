"""A pose param given in a camera's frame (``camera: NAME``) becomes the same world target
as the equivalent pose given in the frame's axes; cameras that cannot serve are refused
with a located error."""

from __future__ import annotations

import json

import numpy as np

from cellrunner.model.geometry import invert, pose_matrix, rpy_deg_of
from tests.commissioning.conftest import cli
from tests.conftest import ROOT

CELL = (ROOT / "cells" / "vision_pick_ur10e.yaml").read_text()
TASK = (ROOT / "tasks" / "vision_pick.yaml").read_text()
CAMERAS = """\
cameras:
  overhead:   # above the belt, calibrated with calibrate-camera
    intrinsics: {fx: 900, fy: 900, cx: 640, cy: 480}
    image_size: [1280, 960]
    mount: camera_zone
    pose: {xyz: [0.012, -0.03, 0.72], rpy: [178.5, 1.2, 91]}
  wrist:
    intrinsics: {fx: 600, fy: 600, cx: 320, cy: 240}
    image_size: [640, 480]
    mount: flange
"""
T_ZONE_CAMERA = pose_matrix([0.012, -0.03, 0.72], [178.5, 1.2, 91])


def _project(tmp_path, task: str):
    (tmp_path / "cells").mkdir(exist_ok=True)
    (tmp_path / "tasks").mkdir(exist_ok=True)
    (tmp_path / "cells" / "c.yaml").write_text(CELL + CAMERAS)
    (tmp_path / "tasks" / "vision_pick.yaml").write_text(task)
    return tmp_path / "cells" / "c.yaml", tmp_path / "tasks" / "vision_pick.yaml"


def _in_camera(xyz, rpy) -> tuple[list[float], list[float]]:
    T = invert(T_ZONE_CAMERA) @ pose_matrix(xyz, rpy)
    return [round(float(v), 6) for v in T[:3, 3]], [round(v, 6) for v in rpy_deg_of(T[:3, :3])]


def _camera_task(default_xyz, default_rpy) -> str:
    spread = np.array([0.03, 0.03, 0.0, 0.0, 0.0, 30.0])  # across the belt, turned about Z
    lo = list(np.add([*default_xyz, *default_rpy], -spread))
    hi = list(np.add([*default_xyz, *default_rpy], spread))
    head, rest = TASK.split("  settle:", 1)
    block = (
        "params:\n  part_pose:\n    type: pose\n    camera: overhead\n"
        f"    min: {json.dumps([round(v, 6) for v in lo])}\n"
        f"    max: {json.dumps([round(v, 6) for v in hi])}\n"
        f"    default: {{xyz: {json.dumps(default_xyz)}, rpy: {json.dumps(default_rpy)}}}\n"
        "  settle:"
    )
    return head.split("params:")[0] + block + rest


def test_a_detection_in_the_camera_frame_gives_the_same_target(tmp_path):
    from cellrunner.model.expand import expand, resolve_params
    from cellrunner.model.load import load_cell, load_task

    seen_xyz, seen_rpy = [0.03, -0.02, 0.0], [0.0, 0.0, 20.0]  # the task's default, in the zone
    cam_xyz, cam_rpy = _in_camera(seen_xyz, seen_rpy)
    cell_path, task_path = _project(tmp_path, TASK)
    cell = load_cell(cell_path)
    by_frame = load_task(task_path, cell)
    targets = {}
    for label, loaded in (("frame", by_frame),):
        steps = expand(loaded, cell.cell, resolve_params(loaded.task, {}))
        targets[label] = next(s.T_world_tcp for s in steps if s.kind == "descend")
    cell_path, task_path = _project(tmp_path, _camera_task(cam_xyz, cam_rpy))
    by_camera = load_task(task_path, load_cell(cell_path))
    assert by_camera.task.params["part_pose"].camera == "overhead"
    given = {"part_pose": json.dumps({"xyz": cam_xyz, "rpy": cam_rpy})}  # as a PLC sends it
    steps = expand(by_camera, cell.cell, resolve_params(by_camera.task, given))
    T = next(s.T_world_tcp for s in steps if s.kind == "descend")
    assert np.allclose(T, targets["frame"], atol=1e-6)  # values written to 1e-6 m, deg
    # and check proves the camera's whole box, through the camera's pose
    r = cli("check", str(cell_path), str(task_path), "--json")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]


def test_cameras_that_cannot_place_a_detection_are_refused(tmp_path):
    task = _camera_task([0, 0, 0.72], [180, 0, 0])
    cell_path, task_path = _project(tmp_path, task.replace("camera: overhead", "camera: wrist"))
    r = cli("validate", str(cell_path), str(task_path))
    assert r.returncode == 2
    assert (
        "vision_pick.yaml:6:13: error: params.part_pose.camera: camera 'wrist' rides on the flange"
        in r.stderr
    )
    cell_path, task_path = _project(tmp_path, task.replace("camera: overhead", "camera: overhed"))
    r = cli("validate", str(cell_path), str(task_path))
    assert r.returncode == 2 and "unknown camera 'overhed' (did you mean 'overhead'?)" in r.stderr
