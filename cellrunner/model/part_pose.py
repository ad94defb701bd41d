"""Where a part lies at its frame (shared by ``check`` and the twin): upright, with the
frame's position and yaw, where a TCP at that frame grips it (centred between jaws, or
its top face under suction cups). This is the part's own frame, the one its ``markers:``
are given in."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.gripper import part_center_depth_m

if TYPE_CHECKING:
    from cellrunner.model.cell import Gripper
    from cellrunner.model.geometry import Shape


def part_pose(T_world_grip: np.ndarray, gripper: Gripper | None, shape: Shape) -> np.ndarray:
    """T_world_part of a part that a TCP at ``T_world_grip`` grips: upright, centred
    (jaws) or with its top face there (suction)."""
    T = upright(T_world_grip)
    T[2, 3] -= part_center_depth_m(gripper, shape)
    return T


def upright(T_world_frame: np.ndarray) -> np.ndarray:
    """A part lies upright at its frame: the frame's position and yaw, no roll or pitch
    (grip frames point their Z down into the part)."""
    x = np.asarray(T_world_frame, float)[:3, 0].copy()
    x[2] = 0.0
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 2] = x, (0.0, 0.0, 1.0)
    T[:3, 1] = np.cross(T[:3, 2], x)
    T[:3, 3] = np.asarray(T_world_frame, float)[:3, 3]
    return T
