"""Hand-eye math on synthetic views (corners projected exactly, then with pixel noise): the
solver recovers the camera, and refuses views that turn about one axis only."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.model.camera import Board
from cellrunner.model.geometry import invert, pose_matrix
from cellrunner.vision.board import BoardView, T_board_cv, charuco
from cellrunner.vision.handeye import CalibrationError, solve

BOARD = Board(squares=[7, 5], square=0.04, marker=0.03)
K = np.array([[620.0, 0, 320], [0, 620, 240], [0, 0, 1]])
X = pose_matrix([0.01, 0.09, 0.03], [2, -1, 91])  # flange -> camera
Z = pose_matrix([0.6, 0.1, 0.8], [0, 0, 4])  # world -> board


def _view(T_world_flange: np.ndarray, noise_px: float, rng) -> BoardView:
    T_cb = invert(T_world_flange @ X) @ Z
    T = T_board_cv(BOARD)
    points = np.asarray(charuco(BOARD).getChessboardCorners(), float) @ T[:3, :3].T + T[:3, 3]
    p = points @ T_cb[:3, :3].T + T_cb[:3, 3]
    pixels = (p[:, :2] / p[:, 2:]) @ K[:2, :2].T + K[:2, 2]
    pixels = pixels + rng.normal(0, noise_px, pixels.shape)
    return BoardView(np.arange(len(points)), pixels, points, T_cb, 0.0)


def _flange_poses(turns_deg) -> list[np.ndarray]:
    out = []
    for rx, ry, rz in turns_deg:
        T_world_camera = (
            Z @ pose_matrix([0, 0, 0], [rx, ry, rz]) @ pose_matrix([0, 0, 0.55], [180, 0, 0])
        )
        out.append(T_world_camera @ invert(X))
    return out


TURNS = [(0, 0, 0), (0, 0, 40), (20, 0, -25), (0, 20, 0), (-20, 5, 25), (5, -22, -25), (15, 15, 20)]


@pytest.mark.parametrize("noise_px", [0.0, 0.2])
def test_solve_recovers_the_camera_on_the_flange(noise_px):
    rng = np.random.default_rng(7)
    flanges = _flange_poses(TURNS)
    views = [_view(F, noise_px, rng) for F in flanges]
    fit = solve(True, flanges, views, K, np.zeros(0))
    D = invert(X) @ fit.T_mount_camera
    assert np.linalg.norm(D[:3, 3]) < (1e-6 if noise_px == 0 else 5e-4)
    assert np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1))) < (
        1e-4 if noise_px == 0 else 0.05
    )
    assert fit.rms_px == pytest.approx(noise_px * np.sqrt(2), abs=0.05)  # 2-D pixel error


def test_solve_refuses_views_turning_about_one_axis():
    rng = np.random.default_rng(1)
    flanges = _flange_poses([(0, 0, a) for a in (0, 15, 30, 45, 60, 75, 90)])
    views = [_view(F, 0.0, rng) for F in flanges]
    with pytest.raises(CalibrationError, match=r"the views turn the camera about too few axes"):
        solve(True, flanges, views, K, np.zeros(0))


def test_solve_needs_six_views():
    rng = np.random.default_rng(2)
    flanges = _flange_poses(TURNS[:5])
    with pytest.raises(CalibrationError, match=r"found in 5 views; calibration needs at least 6"):
        solve(True, flanges, [_view(F, 0.0, rng) for F in flanges], K, np.zeros(0))
