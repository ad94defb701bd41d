"""The twin's cameras as the sim backend serves them: colour images of a cell camera
(:class:`cellrunner.sim.cameras.CameraImager`, one per camera, made on first use) and
depth renderers (:class:`.depth.TwinDepthRenderer`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import BackendError
from cellrunner.sim.description import TwinDescription

if TYPE_CHECKING:
    from cellrunner.backends.sim.depth import TwinDepthRenderer


class TwinCameras:
    """The cameras of one SimBackend's twin."""

    def __init__(self, description: TwinDescription) -> None:
        self.description = description
        self._imagers: dict[str, Any] = {}  # camera name -> CameraImager, made on first use

    def close(self) -> None:
        for imager in self._imagers.values():
            imager.close()
        self._imagers.clear()

    def depth_renderer(
        self, world: Any, camera: str, range_m: tuple[float, float], seed: int
    ) -> TwinDepthRenderer:
        """See :meth:`.backend.SimBackend.depth_renderer`."""
        from cellrunner.backends.sim.depth import TwinDepthRenderer
        from cellrunner.sim.depth import DepthImager

        description = next((c for c in self.description.cameras if c.name == camera), None)
        if description is None:
            raise BackendError(f"the twin has no camera {camera!r}")
        imager = DepthImager(
            world.model, description, range_m, self.description.depth_noise_m, seed=seed
        )
        return TwinDepthRenderer(imager)

    def camera_image(self, world: Any, name: str) -> np.ndarray:
        """See :meth:`.backend.SimBackend.camera_image`."""
        from cellrunner.sim.cameras import CameraImager

        imagers = self._imagers
        if name not in imagers:
            camera = next((c for c in self.description.cameras if c.name == name), None)
            if camera is None:
                raise BackendError(f"the twin has no camera {name!r}")
            imagers[name] = CameraImager(world.model, camera)
        return np.asarray(imagers[name].image(np.array(world.data.qpos)))
