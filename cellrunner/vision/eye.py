"""The cameras as an ``align`` step sees through them (:class:`MarkerEye`): a picture
from ``grab(camera)`` (the twin renders it; on the arm an image source grabs it), the
marker found in it, and the rays through its corners."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cellrunner.model.align import Marker, Sighting
from cellrunner.model.camera import Camera
from cellrunner.vision.marker import find_corners, pose_from_corners, rays


class MarkerEye:
    """An :class:`~cellrunner.execution.context.Eye` over ``grab(camera) -> picture``
    (H x W x 3 RGB or H x W grey, uint8) for the cell's ``cameras``."""

    def __init__(self, grab: Callable[[str], np.ndarray], cameras: dict[str, Camera]) -> None:
        self.grab, self.cameras = grab, cameras
        self.last_pictures: dict[str, np.ndarray] = {}  # each camera's latest (a recording's)

    def sight(self, camera: str, marker: Marker) -> Sighting | None:
        c = self.cameras[camera]
        K = c.intrinsics.matrix()
        distortion = np.asarray(c.intrinsics.distortion, float)
        picture = self.last_pictures[camera] = self.grab(camera)
        corners = find_corners(picture, marker)
        if corners is None:
            return None
        return Sighting(
            rays(corners, K, distortion), pose_from_corners(corners, marker, K, distortion)
        )
