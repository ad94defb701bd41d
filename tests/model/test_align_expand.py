"""How an align step expands: a planned move putting the wrist camera on the marker's axis,
then the look; the later steps aimed at the frame carry the correction key."""

from __future__ import annotations

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.expand import ALIGN_KEY, box_params, expand
from cellrunner.model.load import load_cell, load_task
from tests.conftest import ROOT


def _loaded(task_text: str | None = None, tmp_path=None):
    cell = load_cell(ROOT / "cells" / "align_pick_ur10e.yaml")
    path = ROOT / "tasks" / "align_pick.yaml"
    if task_text is not None:
        path = tmp_path / "t.yaml"
        path.write_text(task_text)
    return cell, load_task(path, cell)


def test_the_camera_looks_down_the_marker_axis_from_the_standoff():
    cell, task = _loaded()
    steps = expand(task, cell.cell, {})
    look, align = steps[1], steps[2]
    assert (look.kind, look.macro, align.kind) == ("move", "align infeed", "align")
    T_world_camera = look.T_world_tcp @ align.extra["T_tcp_camera"]
    T_world_marker = align.extra["T_world_frame"] @ align.extra["T_marker"]
    # the camera's Z points at the marker along the marker's axis, 0.375 m out
    # (600 px focal length x 0.03 m / (10 % of 480 px))
    v = T_world_marker[:3, 3] - T_world_camera[:3, 3]
    assert np.allclose(v, T_world_camera[:3, 2] * 0.375, atol=1e-9)
    assert np.allclose(T_world_camera[:3, 2], -T_world_marker[:3, 2], atol=1e-9)


def test_look_false_looks_from_where_the_arm_stands(tmp_path):
    text = (
        (ROOT / "tasks" / "align_pick.yaml")
        .read_text()
        .replace("      attempts: 3\n", "      attempts: 3\n      look: false\n")
    )
    cell, task = _loaded(text, tmp_path)
    kinds = [s.kind for s in expand(task, cell.cell, {})]
    assert kinds[:3] == ["move", "align", "approach"]


def test_the_correction_moves_only_the_steps_after_the_align_aimed_at_its_frame():
    cell, task = _loaded()
    plain = expand(task, cell.cell, {})
    C = {"xyz": [0.01, -0.005, 0.0], "rpy": [0, 0, 6.0]}
    moved = expand(task, cell.cell, {ALIGN_KEY + "infeed": C})
    F = plain[2].extra["T_world_frame"]
    T_C = geometry.pose_matrix(C["xyz"], C["rpy"])
    for a, b in zip(plain, moved, strict=True):
        if a.T_world_tcp is None:
            continue
        if a.extra.get("aligned_frame") == "infeed":  # the pick's approach and descend
            assert np.allclose(b.T_world_tcp, F @ T_C @ np.linalg.inv(F) @ a.T_world_tcp)
        else:  # the look, the place
            assert np.allclose(a.T_world_tcp, b.T_world_tcp)
    assert [s.kind for s in plain if s.extra.get("aligned_frame")] == ["approach", "descend"]
    assert len(box_params(task)[ALIGN_KEY + "infeed"]) == 9
