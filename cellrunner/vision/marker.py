"""One ArUco marker (the ``align`` step's): the picture printed on a part (the twin's
texture), finding it in an image and its pose in the camera frame.

Marker frame (OpenCV's): origin at the centre of the black square, X to the right of the
printed picture, Y up it, Z out of the printed face. Camera frame: OpenCV's (Z out of the
lens, X right, Y down).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cellrunner.model.align import Marker
from cellrunner.vision.board import cv2

#: px per marker cell in the printed picture
PX_PER_CELL = 40
#: white quiet zone printed around the black square, in cells
MARGIN_CELLS = 1


def _dictionary(name: str) -> Any:
    cv = cv2()
    return cv.aruco.getPredefinedDictionary(getattr(cv.aruco, name))


def _cells(marker: Marker) -> int:
    """Cells along the black square's edge: the bits and the black border."""
    return int(marker.dictionary.split("_")[1].split("X")[0]) + 2


def picture(marker: Marker) -> np.ndarray:
    """The printed sheet: the marker with its white quiet zone (grey, uint8, row 0 at the
    marker's +Y edge)."""
    cv = cv2()
    cells = _cells(marker)
    image = cv.aruco.generateImageMarker(
        _dictionary(marker.dictionary), marker.id, cells * PX_PER_CELL, borderBits=1
    )
    pad = MARGIN_CELLS * PX_PER_CELL
    return np.asarray(np.pad(image, pad, constant_values=255), np.uint8)


def printed_size_m(marker: Marker) -> float:
    """Edge of the printed sheet (the black square and its quiet zone), m."""
    cells = _cells(marker)
    return float(marker.size) * (cells + 2 * MARGIN_CELLS) / cells


def find_corners(image: np.ndarray, marker: Marker) -> np.ndarray | None:
    """The marker's four corners in ``image`` (RGB or grey), px, 4 x 2, in OpenCV's order
    (the printed picture's top left, top right, bottom right, bottom left); None when it
    is not there."""
    cv = cv2()
    grey = cv.cvtColor(image, cv.COLOR_RGB2GRAY) if image.ndim == 3 else image
    parameters = cv.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv.aruco.CORNER_REFINE_SUBPIX
    detector = cv.aruco.ArucoDetector(_dictionary(marker.dictionary), parameters)
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None:
        return None
    found = [c for c, i in zip(corners, ids.ravel(), strict=True) if int(i) == marker.id]
    return np.asarray(found[0].reshape(4, 2), np.float64) if found else None


def corner_points(marker: Marker) -> np.ndarray:
    """The corners in the marker frame (m, 4 x 3), in :func:`find_corners`' order."""
    h = float(marker.size) / 2
    return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], np.float64)


def pose_from_corners(
    corners_px: np.ndarray, marker: Marker, K: np.ndarray, distortion: np.ndarray
) -> np.ndarray | None:
    """T_camera_marker (4x4, m) from the corners (OpenCV's IPPE for squares)."""
    cv = cv2()
    ok, rvec, tvec = cv.solvePnP(
        corner_points(marker), corners_px, K, distortion, flags=cv.SOLVEPNP_IPPE_SQUARE
    )
    if not ok:
        return None
    T = np.eye(4)
    T[:3, :3] = cv.Rodrigues(rvec)[0]
    T[:3, 3] = tvec.ravel()
    return T


def rays(corners_px: np.ndarray, K: np.ndarray, distortion: np.ndarray) -> np.ndarray:
    """Directions in the camera frame (N x 3, z = 1) through the pixels ``corners_px``."""
    cv = cv2()
    xy = cv.undistortPoints(corners_px.reshape(-1, 1, 2), K, distortion).reshape(-1, 2)
    return np.column_stack([xy, np.ones(len(xy))])


def find_marker(
    image: np.ndarray, marker: Marker, K: np.ndarray, distortion: np.ndarray
) -> np.ndarray | None:
    """T_camera_marker (4x4, m) of ``marker`` seen in ``image``, None when it is not there."""
    corners = find_corners(image, marker)
    return None if corners is None else pose_from_corners(corners, marker, K, distortion)
