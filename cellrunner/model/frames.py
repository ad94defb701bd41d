"""Poses of the cell's named frames."""

from __future__ import annotations

import numpy as np

from cellrunner.model.cell import Cell


def frame_pose(cell: Cell, name: str) -> np.ndarray:
    """T_world_frame of a named frame, following parents up to the world."""
    T = np.eye(4)
    seen = set()
    while name != "world":
        if name in seen or name not in cell.frames:
            raise KeyError(name)
        seen.add(name)
        frame = cell.frames[name]
        T = frame.matrix() @ T
        name = frame.parent
    return T
