"""``lift``: a straight line up world +Z from where the TCP stands."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model.step_kinds import register
from cellrunner.model.task import DistanceArgs
from cellrunner.model.units import PositiveLength
from cellrunner.steps._families import RelativeLine

if TYPE_CHECKING:
    import numpy as np


@register
class Lift(RelativeLine):
    name = "lift"
    order = 4
    args = DistanceArgs
    summary = "Straight line up world +Z by `distance` (m)."
    example = 0.1
    short_schema = PositiveLength
    colour = "#e78ac3"

    def relative_goal(self, distance_m: float, T_now: np.ndarray) -> np.ndarray:
        import numpy as np

        from cellrunner.model import geometry

        return np.asarray(geometry.pose_matrix((0, 0, distance_m)) @ T_now)
