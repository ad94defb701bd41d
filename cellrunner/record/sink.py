"""The one Protocol a recording is written through; Rerun's and MCAP's writers implement it.

Entity paths are ``/``-separated names under ``world`` (3D, the world frame of the cell)
or ``plots`` (scalars); times are seconds of the backend's clock. Poses are 4x4 matrices
of the child in its parent (``world/<body>`` in ``world``); points and vertices are in
metres, in the frame of their entity."""

from __future__ import annotations

from typing import Protocol

import numpy as np

#: an RGBA colour, each 0..1
Rgba = tuple[float, float, float, float]


class Sink(Protocol):
    """A recording file being written; every method is called from one worker thread."""

    def mesh(self, path: str, vertices_m: np.ndarray, faces: np.ndarray, rgba: Rgba) -> None:
        """A static triangle mesh (vertices N x 3 in the entity's frame, faces M x 3)."""

    def pose(self, time_s: float, path: str, T_parent_child: np.ndarray) -> None:
        """The entity's pose in its parent at ``time_s``."""

    def line(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        """A polyline (N x 3, world frame) shown from ``time_s`` on (it replaces the last)."""

    def points(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        """A point cloud (N x 3, world frame) from ``time_s`` on (it replaces the last)."""

    def scalar(self, time_s: float, path: str, value: float) -> None:
        """One sample of a plot."""

    def text(self, time_s: float, path: str, text: str, level: str) -> None:
        """A log line (``level``: INFO, WARN or ERROR)."""

    def depth(self, time_s: float, path: str, depth_m: np.ndarray) -> None:
        """A depth image (H x W, metres; 0 or inf: no return)."""

    def image(self, time_s: float, path: str, rgb: np.ndarray) -> None:
        """A camera's picture (H x W x 3 RGB or H x W grey, uint8)."""

    def close(self) -> None:
        """Flush and close the file."""
