"""The twin's depth cameras behind :class:`~cellrunner.backends.base.RendersDepth`: a copy
of the scene taken on the control thread (:class:`DepthScene`) and a renderer of one camera
(:class:`TwinDepthRenderer`) over :class:`cellrunner.sim.depth.DepthImager`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from cellrunner.sim.depth import DepthImager


@dataclass(frozen=True)
class DepthScene:
    """What a depth image of the twin depends on: its joints and its mocap bodies (the
    intruders), copied."""

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray

    @classmethod
    def of(cls, data: Any) -> DepthScene:
        """A copy of MuJoCo ``data``'s joints and mocap bodies."""
        return cls(np.array(data.qpos), np.array(data.mocap_pos), np.array(data.mocap_quat))


class TwinDepthRenderer:
    """One depth camera of the twin's compiled model (a :class:`DepthRenderer`)."""

    def __init__(self, imager: DepthImager) -> None:
        self._imager = imager

    def frame(self, scene: object, time_s: float) -> Any:  # a perception DepthFrame
        assert isinstance(scene, DepthScene), "a scene from SimBackend.depth_scene"
        return self._imager.frame(scene.qpos, scene.mocap_pos, scene.mocap_quat, time_s)

    def close(self) -> None:
        self._imager.close()
