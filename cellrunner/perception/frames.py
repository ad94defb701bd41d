"""A depth image as the map reads it, and its back-projection to points.

Frames are OpenCV's (:mod:`cellrunner.model.camera`): the camera frame has Z out of the
lens, X right, Y down; a depth is the distance along Z (m), 0 where the camera measured
nothing (out of range, no return, masked).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class DepthFrame:
    """``depth_m`` (H x W, float32, m along the camera's Z, 0 = no depth) taken by camera
    ``camera`` at ``time_s`` (the robot's clock) from ``T_world_camera``, with pinhole
    intrinsics ``K`` (3 x 3, px) for this image's size; ``q_rad`` the arm's joints at
    capture where the source knows them (the twin), else None (looked up by time)."""

    camera: str
    time_s: float
    depth_m: np.ndarray
    T_world_camera: np.ndarray
    K: np.ndarray
    q_rad: np.ndarray | None = None
    distortion: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def size(self) -> tuple[int, int]:
        """Width and height, px."""
        return int(self.depth_m.shape[1]), int(self.depth_m.shape[0])


class RayTable:
    """For every pixel of one camera's image, the direction (x/z, y/z) of its ray in the
    camera frame (undistorted through OpenCV's model when there is distortion); built once
    per camera and image size."""

    def __init__(self, K: np.ndarray, width: int, height: int, distortion: np.ndarray) -> None:
        self.K, self.width, self.height = np.asarray(K, float), width, height
        u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        if distortion is not None and len(distortion) and np.any(distortion):
            import cv2

            pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
            rays = cv2.undistortPoints(pixels, self.K, np.asarray(distortion, float)).reshape(-1, 2)
            x, y = rays[:, 0], rays[:, 1]
        else:
            x = ((u - K[0, 2]) / K[0, 0]).ravel()
            y = ((v - K[1, 2]) / K[1, 1]).ravel()
        self.x = x.astype(np.float32)
        self.y = y.astype(np.float32)

    def matches(self, frame: DepthFrame) -> bool:
        return frame.size == (self.width, self.height) and np.array_equal(frame.K, self.K)

    def points(self, depth_m: np.ndarray, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The valid pixels' points in the camera frame (N x 3, m) and their flat pixel
        indices (N); every ``stride``-th pixel along each axis."""
        if stride > 1:
            mask = np.zeros(depth_m.shape, bool)
            mask[::stride, ::stride] = True
            z = np.where(mask, depth_m, 0).ravel()
        else:
            z = depth_m.ravel()
        index = np.flatnonzero(z > 0)
        zs = z[index]
        points = np.empty((len(index), 3), np.float32)
        points[:, 0] = self.x[index] * zs
        points[:, 1] = self.y[index] * zs
        points[:, 2] = zs
        return points, index
