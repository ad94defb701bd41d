"""`calibrate-camera` against `cellrunner twin`: the twin renders the camera where it truly
is (its own cell file, hidden from the command), the command's cell file says something
centimetres and degrees off. Judged: the written pose within 1 mm / 0.2 deg of the truth,
and the cell file changed in that pose's line only."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.model.geometry import invert
from tests.commissioning.conftest import CELL, cli, twin, write_project

HOST = "127.0.0.220"

WRIST = """\
cameras:
  wrist:   # on the flange, beside the tool
    intrinsics: {fx: 620, fy: 615, cx: 322.5, cy: 236.0, distortion: [-0.05, 0.02, 0, 0, 0]}
    image_size: [640, 480]
    mount: flange
    pose: {xyz: [0, 0.085, 0.03], rpy: [0, 0, 0]}   # from the bracket's drawing
    board: {squares: [7, 5], square: 0.04, marker: 0.03, pose: {xyz: [0.6, 0.1, 0.803]}}
"""
WRIST_TRUE = ("[0, 0.085, 0.03], rpy: [0, 0, 0]", "[0.0042, 0.0907, 0.0268], rpy: [2.4, -1.6, 1.7]")
BOARD_TRUE = ("[0.6, 0.1, 0.803]}", "[0.612, 0.088, 0.803], rpy: [0, 0, 3.5]}")

OVERHEAD = """\
cameras:
  overhead:   # on a gantry above the bench, looking down
    intrinsics: {fx: 600, fy: 600, cx: 319.5, cy: 239.5}
    image_size: [640, 480]
    pose: {xyz: [0.62, 0.25, 1.75], rpy: [180, 0, 90]}
    board: {squares: [5, 4], square: 0.03, marker: 0.022, mount: flange, pose: {xyz: [0, 0, 0.11]}}
"""
OVERHEAD_TRUE = (
    "[0.62, 0.25, 1.75], rpy: [180, 0, 90]",
    "[0.6315, 0.2384, 1.7612], rpy: [178.3, 1.9, 88.6]",
)
FLANGE_BOARD_TRUE = ("[0, 0, 0.11]}", "[0.003, -0.002, 0.112], rpy: [0, 0, 2]}")


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def _calibrate(tmp_path, block: str, name: str, truths) -> tuple[str, str, str]:
    cell_text = CELL + block
    cell, _ = write_project(tmp_path, cell_text)
    true_text = cell_text
    for wrong, right in truths:
        true_text = true_text.replace(wrong, right)
    hidden = tmp_path / "cells" / "hidden_truth.yaml"
    hidden.write_text(true_text)
    with twin(hidden, HOST):
        r = cli("calibrate-camera", str(cell), name, "--robot-host", HOST, "--yes", timeout_s=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return cell_text, cell.read_text(), r.stderr


def _pose_error(cell_path, true_path, name) -> tuple[float, float]:
    from cellrunner.model.load import load_cell

    got = load_cell(cell_path).cell.cameras[name].pose.matrix()
    want = load_cell(true_path).cell.cameras[name].pose.matrix()
    D = invert(want) @ got
    return float(np.linalg.norm(D[:3, 3])), _angle_deg(D[:3, :3])


@pytest.mark.parametrize(
    ("block", "name", "truths"),
    [
        (WRIST, "wrist", (WRIST_TRUE, BOARD_TRUE)),
        (OVERHEAD, "overhead", (OVERHEAD_TRUE, FLANGE_BOARD_TRUE)),
    ],
    ids=["eye-in-hand", "eye-to-hand"],
)
def test_calibrate_camera_recovers_a_hidden_camera_pose(tmp_path, block, name, truths):
    before, after, err = _calibrate(tmp_path, block, name, truths)
    cell = tmp_path / "cells" / "c.yaml"
    error_m, error_deg = _pose_error(cell, tmp_path / "cells" / "hidden_truth.yaml", name)
    print(f"{name}: {error_m * 1000:.3f} mm, {error_deg:.4f} deg from the hidden pose")  # -s
    assert error_m < 1e-3 and error_deg < 0.2, (error_m, error_deg, err[-1500:])
    old, new = before.splitlines(True), after.splitlines(True)
    changed = [i for i, (a, b) in enumerate(zip(old, new, strict=True)) if a != b]
    assert len(changed) == 1, "only the camera's pose line changes"
    assert new[changed[0]].startswith("    pose: {xyz: [")
    assert "hand-eye from " in err and " px rms" in err and "1-sigma" in err


def test_calibrate_camera_refuses_bad_arguments_without_moving(tmp_path):
    cell, _ = write_project(tmp_path, CELL + WRIST)
    r = cli("calibrate-camera", str(cell), "wirst", "--robot-host", "127.0.0.229")
    assert r.returncode == 2, r.stderr
    assert "unknown camera 'wirst'; known: wrist" in r.stderr
    r = cli("calibrate-camera", str(cell), "wrist", "--robot-host", "127.0.0.229", "--views", "3")
    assert r.returncode == 2 and "--views 3: give 6 to 40" in r.stderr
    no_board = CELL + WRIST.split("    board:")[0]
    cell, _ = write_project(tmp_path, no_board)
    r = cli("calibrate-camera", str(cell), "wrist", "--robot-host", "127.0.0.229")
    assert r.returncode == 2 and "camera 'wrist' has no board: add cameras.wrist.board" in r.stderr
    cell, _ = write_project(tmp_path, CELL + WRIST)
    r = cli("calibrate-camera", str(cell), "wrist", "--robot-host", "127.0.0.229")
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
