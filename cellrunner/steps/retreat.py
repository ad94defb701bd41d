"""``retreat``: a straight line back along the tool's -Z from where the TCP stands."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model.step_kinds import register
from cellrunner.model.task import DistanceArgs
from cellrunner.model.units import PositiveLength
from cellrunner.steps._families import RelativeLine

if TYPE_CHECKING:
    import numpy as np


@register
class Retreat(RelativeLine):
    name = "retreat"
    order = 5
    args = DistanceArgs
    summary = "Straight line back along the tool's -Z by `distance` (m)."
    example = 0.05
    short_schema = PositiveLength
    colour = "#e78ac3"

    def relative_goal(self, distance_m: float, T_now: np.ndarray) -> np.ndarray:
        import numpy as np

        from cellrunner.model import geometry

        return np.asarray(T_now @ geometry.pose_matrix((0, 0, -distance_m)))
