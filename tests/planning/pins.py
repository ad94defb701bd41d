"""Obstacles placed where a sampled joint move would miss them."""

from __future__ import annotations

import numpy as np


def pin_between_samples(kin, a, b, tool_centre_z_m: float, tool_radius_m: float) -> np.ndarray:
    """Where a 2 mm pin sits 3 mm inside a flange-mounted tool cylinder's rim (centre
    ``tool_centre_z_m`` along the flange's z) halfway between two of the planner's samples
    of the joint move a -> b, a turn of the base: on the side away from the base axis,
    where each sample's cylinder passes clear of it and the swept one does not."""
    import math

    from cellrunner.planning.joint_path import LAZY_RESOLUTION_RAD

    n = math.ceil(float(np.linalg.norm(b - a)) / LAZY_RESOLUTION_RAD)
    T = kin.T_world_flange(a + (n // 2 + 0.5) / n * (b - a))
    centre = T[:3, :3] @ np.array([0, 0, tool_centre_z_m]) + T[:3, 3]
    radial = np.array([centre[0], centre[1], 0.0]) / np.hypot(centre[0], centre[1])
    return centre + (tool_radius_m - 0.003) * radial
