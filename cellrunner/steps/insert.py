"""``insert``: straight in to a frame and ``depth`` past it under a force limit; ending
outside ``expect_depth`` is a failed place (3)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.force_steps import InsertArgs
from cellrunner.model.step_kinds import register
from cellrunner.steps._families import GuardedLine

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck


@register
class Insert(GuardedLine):
    name = "insert"
    order = 14
    args = InsertArgs
    summary = (
        "Straight in to a frame and `depth` (m) past it under a force limit; ending outside "
        "`expect_depth` is a failed place (3)."
    )
    example: ClassVar[Any] = {
        "to": "hole",
        "depth": 0.02,
        "speed": 0.005,
        "force": {"max": 20},
        "expect_depth": [0.018, 0.021],
    }

    def target(self, builder: Expansion, args: Any) -> tuple[str, np.ndarray | None, Any]:
        # the line ends ``depth`` past the frame, along its Z
        from cellrunner.model import geometry

        T, name = builder.target(args.to, None, args.pattern)
        return name, T @ geometry.pose_matrix((0, 0, args.depth)), None

    def target_frame(self, args: Any) -> str | None:
        return str(args.to)

    def check_line(self, planner: Any, step: Any, path: np.ndarray) -> None:
        """It must reach ``expect_depth`` before it meets a fixture not in ``contact:``,
        and slide into the fixtures named there, not jam on them."""
        from cellrunner.errors import InfeasibleError
        from cellrunner.planning.insert_fit import early_stop, jam

        kin, carrying = planner.world.kinematics, planner.part is not None
        bare = planner.world.collision.carrying(planner.part)
        failure = early_stop(kin, step, bare, path, carrying) or jam(kin, step, bare, path)
        if failure is not None:
            raise InfeasibleError(failure)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        refs.frame(spec.args.to, spec.path + ("to",))
        refs.contacts(spec.args, spec.path)
