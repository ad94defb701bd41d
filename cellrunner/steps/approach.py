"""``approach``: a planned joint move to ``distance`` back from a frame along its Z."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.step_kinds import Motion, register
from cellrunner.model.task import ApproachArgs
from cellrunner.steps._families import FrameLine

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.expand import Expansion


@register
class Approach(FrameLine):
    name = "approach"
    order = 1
    args = ApproachArgs
    motion: ClassVar[Motion | None] = "planned"
    summary = "Planned move to `distance` back from a frame along its Z."
    example: ClassVar[Any] = {"to": "infeed", "distance": 0.1}
    colour = "#66c2a5"

    def target(self, builder: Expansion, args: Any) -> tuple[str, np.ndarray | None, Any]:
        from cellrunner.model import geometry

        T, name = builder.target(args.to, args.offset, args.pattern)
        return name, T @ geometry.pose_matrix((0, 0, -args.distance)), None
