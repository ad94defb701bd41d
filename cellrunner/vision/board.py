"""The ChArUco calibration board of a camera block: its OpenCV object, the picture printed
on it (the twin's texture), and finding it in an image.

Frames: the cell's **board frame** has its origin at the centre of the checkered area, Z out
of the printed face, X along ``squares[0]``, Y along ``squares[1]`` (see
:mod:`cellrunner.model.camera`). OpenCV's board frame (its object points) has its origin at
the checkered area's corner that the picture shows top left, x along the picture's columns,
y down its rows, z into the board. :func:`T_board_cv` relates the two.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.errors import CellrunnerError
from cellrunner.model.camera import Board

#: the printed picture's resolution, px per square
PX_PER_SQUARE = 120
#: white margin printed around the checkered area, in squares (ChArUco needs a quiet zone)
MARGIN_SQUARES = 0.5
#: fewest ChArUco corners a view needs to give a pose
MIN_CORNERS = 8


class VisionUnavailable(CellrunnerError):
    """OpenCV is not installed (the ``vision`` extra)."""


def cv2() -> Any:
    """OpenCV, or VisionUnavailable saying how to install it."""
    try:
        import cv2 as module
    except ImportError as exc:
        raise VisionUnavailable(
            "camera calibration needs OpenCV: pip install 'cellrunner[vision]' "
            f"(opencv-python-headless 4.x) ({exc})"
        ) from None
    if not hasattr(module, "calibrateHandEye") or not hasattr(module.aruco, "CharucoDetector"):
        raise VisionUnavailable(
            f"OpenCV {module.__version__} lacks calibrateHandEye or the ChArUco detector; "
            "install opencv-python-headless>=4.8,<5 (pip install 'cellrunner[vision]')"
        )
    return module


def charuco(board: Board) -> Any:
    """OpenCV's CharucoBoard of ``board`` (m)."""
    cv = cv2()
    dictionary = cv.aruco.getPredefinedDictionary(getattr(cv.aruco, board.dictionary))
    return cv.aruco.CharucoBoard(
        tuple(board.squares), float(board.square), float(board.marker), dictionary
    )


def T_board_cv(board: Board) -> np.ndarray:
    """OpenCV's board frame in the cell's board frame (a 180 deg turn about X, to the
    corner at -X, +Y)."""
    width_m, height_m = board.size_m
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = (-width_m / 2, height_m / 2, 0.0)
    return T


def printed_size_m(board: Board) -> tuple[float, float]:
    """Width and height of the whole printed sheet, margin included, m."""
    width_m, height_m = board.size_m
    margin_m = 2 * MARGIN_SQUARES * board.square
    return width_m + margin_m, height_m + margin_m


def picture(board: Board) -> np.ndarray:
    """The printed sheet as a grey image (rows top to bottom: the sheet's +Y edge first)."""
    margin_px = round(MARGIN_SQUARES * PX_PER_SQUARE)
    size = (
        board.squares[0] * PX_PER_SQUARE + 2 * margin_px,
        board.squares[1] * PX_PER_SQUARE + 2 * margin_px,
    )
    return np.asarray(charuco(board).generateImage(size, marginSize=margin_px, borderBits=1))


@dataclass(frozen=True)
class BoardView:
    """The board seen in one image: ChArUco corner ids, their pixels, their points in the
    cell's board frame (m), and the board's pose in the camera frame from PnP."""

    ids: np.ndarray  # (n,)
    pixels: np.ndarray  # (n, 2)
    points_board_m: np.ndarray  # (n, 3)
    T_camera_board: np.ndarray
    rms_px: float  # PnP reprojection error


def find_board(
    image: np.ndarray, board: Board, K: np.ndarray, distortion: np.ndarray
) -> BoardView | None:
    """The board in ``image`` (grey or RGB), or None when fewer than MIN_CORNERS corners
    are found."""
    cv = cv2()
    grey = image if image.ndim == 2 else cv.cvtColor(image, cv.COLOR_RGB2GRAY)
    cb = charuco(board)
    corners, ids, _, _ = cv.aruco.CharucoDetector(cb).detectBoard(grey)
    if ids is None or len(ids) < MIN_CORNERS:
        return None
    ids = ids.ravel()
    pixels = corners.reshape(-1, 2).astype(float)
    T_bc = T_board_cv(board)
    points_cv = np.asarray(cb.getChessboardCorners(), float)[ids]
    points = points_cv @ T_bc[:3, :3].T + T_bc[:3, 3]
    ok, rvec, tvec = cv.solvePnP(points, pixels, K, distortion, flags=cv.SOLVEPNP_ITERATIVE)
    if not ok:
        return None
    projected, _ = cv.projectPoints(points, rvec, tvec, K, distortion)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - pixels) ** 2, axis=1))))
    T = np.eye(4)
    T[:3, :3] = cv.Rodrigues(rvec)[0]
    T[:3, 3] = tvec.ravel()
    return BoardView(ids, pixels, points, T, rms)
