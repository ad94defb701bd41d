"""The expanded primitive :class:`Step` and the kinds of steps."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np


class StepKind(enum.StrEnum):
    """Every kind of step a task file may write, and the primitives they expand into."""

    MOVE = "move"
    APPROACH = "approach"
    DESCEND = "descend"
    LINEAR = "linear"
    LIFT = "lift"
    RETREAT = "retreat"
    GRIP = "grip"
    RELEASE = "release"
    SET_OUTPUT = "set_output"
    WAIT_INPUT = "wait_input"
    WAIT = "wait"
    MOVE_UNTIL_CONTACT = "move_until_contact"
    INSERT = "insert"
    PICK = "pick"
    PLACE = "place"
    CHANGE_TOOL = "change_tool"
    TOOL_LOCK = "tool_lock"
    TOOL_UNLOCK = "tool_unlock"
    ALIGN = "align"


K = StepKind
#: straight TCP lines stopped by the wrist force
FORCE_KINDS = (K.MOVE_UNTIL_CONTACT, K.INSERT)
MOTION_KINDS = (K.MOVE, K.APPROACH, K.DESCEND, K.LINEAR, K.LIFT, K.RETREAT, *FORCE_KINDS)
PLANNED_KINDS = (K.MOVE, K.APPROACH)  # collision-free planned joint moves
LINEAR_KINDS = (K.DESCEND, K.LINEAR, K.LIFT, K.RETREAT, *FORCE_KINDS)  # straight TCP lines


@dataclass(frozen=True)
class RetryPlan:
    """What a grip does when its confirmation fails: run ``between``, then redo the steps
    from ``redo_from`` (1-based expanded index), at most ``attempts`` times in all."""

    attempts: int
    between: tuple[Step, ...]
    redo_from: int


@dataclass(frozen=True, eq=False)
class Step:
    """One expanded primitive step.

    ``T_world_tcp`` is the goal pose of the TCP for frame targets (approach point for
    ``approach``); ``q_goal_deg`` for joint targets (``home`` included); both None for
    relative motions (lift, retreat) and non-motion steps.
    """

    index: int
    kind: StepKind
    name: str
    args: Any
    file_path: tuple[Any, ...]  # where the step is written in its file (a PathKey)
    macro: str | None = None
    T_world_tcp: np.ndarray | None = None
    q_goal_deg: tuple[float, ...] | None = None
    retry: RetryPlan | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", StepKind(self.kind))  # a kind read from a file

    @property
    def is_motion(self) -> bool:
        return self.kind in MOTION_KINDS

    @property
    def label(self) -> str:
        """``step 5 approach 'far_away'``, as messages name a step."""
        return (
            f"step {self.index} {self.kind} {self.name!r}"
            if self.name != self.kind
            else f"step {self.index} {self.kind}"
        )
