"""``move_until_contact``: a straight line along a direction until the wrist force rises;
failing without contact within ``max_distance``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.force_steps import MoveUntilContactArgs
from cellrunner.model.step_kinds import register
from cellrunner.steps._families import GuardedLine

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlanner


@register
class MoveUntilContact(GuardedLine):
    name = "move_until_contact"
    order = 13
    args = MoveUntilContactArgs
    summary = (
        "Straight line along `direction` until the wrist force rises by `force` (N); "
        "fails without contact within `max_distance` (m)."
    )
    example: ClassVar[Any] = {
        "direction": [0, 0, 1],
        "frame": "tool",
        "speed": 0.01,
        "force": 10,
        "max_distance": 0.05,
    }

    def line_goal(self, planner: Any, step: Step, T_now: np.ndarray) -> np.ndarray:
        from cellrunner.planning.force_plan import contact_line_goal

        return contact_line_goal(step.args, T_now)

    def check_line(self, planner: StepPlanner, step: Step, path: np.ndarray) -> None:
        """It must touch something the cell file has (a fixture, a waiting part) within its
        max_distance, or the step fails on every backend (no contact)."""
        from cellrunner.errors import InfeasibleError
        from cellrunner.planning.force_plan import first_touch, meets_nothing

        bare = planner.world.collision.carrying(planner.part)
        if first_touch(bare, path, planner.part is not None) is None:
            raise InfeasibleError(meets_nothing(step, bare, path[-1], planner.part is not None))
