"""The camera proofs of check (issue 33): the projection agrees with OpenCV's, the
predicted noise of one look agrees with OpenCV's pose solver fed noisy corners, and a
watch camera that looks away from its zone is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cellrunner.model.camera import Camera
from cellrunner.model.geometry import pose_matrix
from cellrunner.planning.camera_view import project
from cellrunner.planning.marker_noise import CORNER_NOISE_PX, look_noise
from tests.conftest import ROOT
from tests.rig import cli_json

cv2 = pytest.importorskip("cv2")

CAMERA = Camera.model_validate(
    {
        "intrinsics": {"fx": 600, "fy": 600, "cx": 319.5, "cy": 239.5,
                       "distortion": [0.05, -0.1, 0.001, -0.002, 0.01]},
        "image_size": [640, 480],
    }
)  # fmt: skip


def test_the_projection_is_opencvs_with_its_distortion():
    rng = np.random.default_rng(3)
    points = rng.uniform([-0.2, -0.15, 0.3], [0.2, 0.15, 1.0], size=(50, 3))
    T_world_camera = pose_matrix((0.1, -0.05, 0.2), (5, -3, 20))
    world = points @ T_world_camera[:3, :3].T + T_world_camera[:3, 3]
    view = project(CAMERA, T_world_camera, world)
    expected, _ = cv2.projectPoints(
        points, np.zeros(3), np.zeros(3), CAMERA.intrinsics.matrix(),
        np.asarray(CAMERA.intrinsics.distortion),
    )  # fmt: skip
    assert np.abs(view.uv_px - expected.reshape(-1, 2)).max() < 1e-6
    assert np.allclose(view.depth_m, points[:, 2])


def _solved_spread(size_m: float, standoff_m: float, trials: int = 400) -> tuple[float, ...]:
    """The std of x (m) and the turn (rad) read in the marker's plane, and of z (m), the
    turn about the line of sight and a tilt (rad) that OpenCV's IPPE solver gives for a marker facing the camera at ``standoff_m``, its
    corners found with CORNER_NOISE_PX of noise."""
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    h = size_m / 2
    corners = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]])
    true_px, _ = cv2.projectPoints(corners, np.zeros(3), np.array([0, 0, standoff_m]), K, None)
    rng = np.random.default_rng(7)
    rows = []
    for _ in range(trials):
        seen = true_px.reshape(-1, 2) + rng.normal(0, CORNER_NOISE_PX, (4, 2))
        ok, rvec, tvec = cv2.solvePnP(corners, seen, K, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        assert ok
        R, _ = cv2.Rodrigues(rvec)
        # x as a planar look reads it: the corners' rays cut with the marker's known plane
        cuts = (seen - K[:2, 2]) / K[0, 0] * standoff_m
        x_planar = float(np.mean(cuts[:, 0]))
        a, b = corners[:, :2], cuts - cuts.mean(axis=0)  # marker axes = camera axes
        H = a.T @ b
        turn_planar = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
        tilt = math.asin(max(-1.0, min(1.0, R[2, 1])))
        turn = math.atan2(R[1, 0], R[0, 0])
        rows.append([x_planar, turn_planar, tvec[2, 0], turn, tilt])
    return tuple(float(v) for v in np.std(np.array(rows), axis=0))


@pytest.mark.parametrize(
    ("size_m", "standoff_m"), [(0.03, 0.375), (0.05, 0.3), (0.02, 0.5), (0.1, 0.3), (0.03, 0.1)]
)
def test_the_predicted_noise_of_a_look_is_what_opencv_reads(size_m, standoff_m):
    x, turn_planar, z, turn, tilt = _solved_spread(size_m, standoff_m)
    f, s, Z, sigma = 600.0, size_m, standoff_m, CORNER_NOISE_PX
    a = f * s / Z
    predicted = {
        "x": sigma * Z / (2 * f),
        "turn in the plane": sigma / (a * math.sqrt(2)),
        "z": sigma * Z / (1.2 * a),
        "turn": sigma / a,
        "tilt": math.sqrt(1.6 * sigma / a),
    }
    measured = {"x": x, "turn in the plane": turn_planar, "z": z, "turn": turn, "tilt": tilt}
    for axis, p in predicted.items():
        assert 0.8 < measured[axis] / p < 1.25, (axis, measured[axis], p)
    # look_noise combines them: planar x, y, rz; the full pose adds z and the tilts
    planar = look_noise(s, Z, f, 0.0, full_pose=False)
    full = look_noise(s, Z, f, 0.0, full_pose=True)
    assert planar.rotation_rad == pytest.approx(predicted["turn in the plane"])
    assert planar.position_m == pytest.approx(math.sqrt(2) * predicted["x"])
    assert full.rotation_rad == pytest.approx(
        math.sqrt(predicted["turn"] ** 2 + 2 * predicted["tilt"] ** 2)
    )


def test_a_watch_camera_rolled_to_the_ceiling_is_refused(tmp_path):
    text = (ROOT / "cells" / "watched_ur5e.yaml").read_text()
    good = "pose: {xyz: [0.35, 0, 2.3], rpy: [180, 0, 90]}"
    assert good in text
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    task = tmp_path / "tasks" / "t.yaml"
    task.write_text("task: t\nsteps:\n  - move: home\n")
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(text)
    code, out = cli_json("check", str(cell), str(task))
    assert code == 0, out["errors"]
    # the camera's mount slipped half a turn about its roll: it looks at the ceiling
    cell.write_text(text.replace(good, "pose: {xyz: [0.35, 0, 2.3], rpy: [0, 0, 90]}"))
    code, out = cli_json("check", str(cell), str(task))
    assert code == 1
    (error,) = out["errors"]
    assert error.startswith(
        "watch camera 'overhead': the watch cameras see 0% of the 1.3 x 1 x 0.9 m zone"
    ), error
    assert "looks along [+0.00, +0.00, +1.00] (world)" in error, error


def test_a_sight_line_through_a_body_is_found_and_its_distance_given():
    from cellrunner.model.geometry import Box, Cylinder
    from cellrunner.planning.sight import first_in_the_way

    eye = np.zeros(3)
    targets = np.array([[0.0, 0.0, 0.2], [0.02, 0.0, 0.2]])
    body = Cylinder(0.01, 0.04)  # along Z, 50-90 mm out, 15 mm beside the straight line
    beside = [("tool geometry 'body'", body, pose_matrix((0.015, 0, 0.07), (0, 0, 0)))]
    # the line to the first target passes 15 mm from the axis: clear; to the second it
    # reaches 0.02 x 0.05/0.2 = 5 mm over by the body's near end: inside its 10 mm radius
    hit = first_in_the_way(eye, targets, beside, 200, 0.003)
    assert hit is not None and hit[0] == "tool geometry 'body'"
    assert hit[1] == pytest.approx(0.0501, abs=0.002)
    assert first_in_the_way(eye, targets[:1], beside, 200, 0.003) is None
    # the target's own carrier, right under it, is left out
    under = [("fixture 'table'", Box((0.1, 0.1, 0.01)), pose_matrix((0, 0, 0.2), (0, 0, 0)))]
    assert first_in_the_way(eye, targets[:1], under, 200, 0.006) is None
