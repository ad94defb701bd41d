"""Where an align finds its frame: the marker's corners projected through a pinhole camera
(what a camera sees), then :func:`frame_correction` must give back the part's offset,
in the plane (x, y, yaw) and in full (IPPE); and the printed marker is found in a picture."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.execution.align import frame_correction
from cellrunner.model import geometry
from cellrunner.model.align import Marker, Sighting

MARKER = Marker(id=7, size=0.03, pose={"xyz": [0, 0, -0.02], "rpy": [180, 0, 0]})
F = geometry.pose_matrix((0.7, -0.3, 0.825), (180, 0, 0))  # grip frames point Z down
K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])


def corners_seen(C: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
    """Rays (camera frame, z = 1) through the marker's corners, the frame at F @ C."""
    h = MARKER.size / 2
    corners = np.array([[-h, h, 0, 1], [h, h, 0, 1], [h, -h, 0, 1], [-h, -h, 0, 1]])
    p = (np.linalg.inv(T_world_camera) @ F @ C @ MARKER.pose.matrix() @ corners.T).T[:, :3]
    return p / p[:, 2:3]


def camera_above(dx: float = -0.0, dy: float = 0.0) -> np.ndarray:
    """A camera 0.3 m above the marker, looking down (Z into the table)."""
    return F @ geometry.pose_matrix((dx, dy, -0.32))


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-0.015, 0.015),
    y=st.floats(-0.015, 0.015),
    yaw=st.floats(-8, 8),
    cam=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
)
def test_the_plane_cut_gives_back_the_offset(x, y, yaw, cam):
    C = geometry.pose_matrix((x, y, 0), (0, 0, yaw))
    T_wc = camera_above(*cam)
    found = frame_correction(Sighting(corners_seen(C, T_wc), None), MARKER, T_wc, F, planar=True)
    assert np.allclose(found, C, atol=1e-9)


def test_half_a_pixel_of_noise_moves_the_plane_cut_less_than_half_a_millimetre():
    rng = np.random.default_rng(3)
    C = geometry.pose_matrix((0.008, 0.006, 0), (0, 0, 4))
    T_wc = camera_above()
    rays = corners_seen(C, T_wc)
    rays[:, :2] += rng.normal(0, 0.5 / 600, (4, 2))  # half a pixel
    found = frame_correction(Sighting(rays, None), MARKER, T_wc, F, planar=True)
    assert np.linalg.norm(found[:3, 3] - C[:3, 3]) < 5e-4


def test_the_full_pose_path_uses_the_solved_pose():
    C = geometry.pose_matrix((0.004, -0.003, 0.002), (1, -2, 5))
    T_wc = camera_above()
    T_cm = np.linalg.inv(T_wc) @ F @ C @ MARKER.pose.matrix()
    found = frame_correction(Sighting(corners_seen(C, T_wc), T_cm), MARKER, T_wc, F, planar=False)
    assert np.allclose(found, C, atol=1e-9)
    assert frame_correction(Sighting(corners_seen(C, T_wc), None), MARKER, T_wc, F, False) is None


def test_the_printed_marker_is_found_where_it_was_drawn():
    import cv2

    from cellrunner.vision.marker import find_corners, picture

    sheet = picture(MARKER)
    canvas = np.full((480, 640), 200, np.uint8)
    canvas[80 : 80 + sheet.shape[0], 150 : 150 + sheet.shape[1]] = sheet
    corners = find_corners(cv2.cvtColor(canvas, cv2.COLOR_GRAY2RGB), MARKER)
    assert corners is not None
    # the black square starts one cell (40 px) inside the white quiet zone
    assert np.allclose(corners[0], [150 + 40 - 0.5, 80 + 40 - 0.5], atol=1.0)
    assert find_corners(canvas, Marker(id=8, size=0.03)) is None, "another id is not it"
