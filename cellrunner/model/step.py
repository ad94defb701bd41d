"""The expanded primitive :class:`Step` and the kinds of steps."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from cellrunner.model.step_kinds import Motion, kind_of

if TYPE_CHECKING:
    import numpy as np


class StepKind(enum.StrEnum):
    """The names of the built-in step kinds, for code that asks about one of them by name.
    What a kind is and does lives in its module (:mod:`cellrunner.steps`); a kind added
    there needs no name here: :attr:`Step.kind` holds any registered kind's name."""

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


class Macro(str):
    """The step a primitive was expanded from, as messages and reports name it (``place
    outfeed``), knowing its kind: code asks :attr:`Step.macro_kind`, never the text."""

    kind: str

    def __new__(cls, kind: str, target: str | None = None) -> Macro:
        macro = super().__new__(cls, kind if target is None else f"{kind} {target}")
        macro.kind = kind
        return macro

    def __reduce__(self) -> tuple[Any, ...]:  # pickled (the plan store) with its kind
        target = str(self)[len(self.kind) + 1 :] or None
        return (Macro, (self.kind, target))


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
    kind: str  # a registered step kind (a StepKind for the built-in ones)
    name: str
    args: Any
    file_path: tuple[Any, ...]  # where the step is written in its file (a PathKey)
    macro: str | None = None
    T_world_tcp: np.ndarray | None = None
    q_goal_deg: tuple[float, ...] | None = None
    retry: RetryPlan | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        kind = kind_of(self.kind)  # a kind read from a file: StepKindError if unknown
        if kind.name in StepKind.__members__.values():
            object.__setattr__(self, "kind", StepKind(kind.name))

    @property
    def macro_kind(self) -> str | None:
        """The kind of the step this one was expanded from (``place``, ``pick``,
        ``on_error``, ...), None for a step written as it is."""
        return self.macro.kind if isinstance(self.macro, Macro) else None

    @property
    def motion(self) -> Motion | None:
        """How the step moves the arm (its kind's), or None."""
        return kind_of(self.kind).motion

    @property
    def is_motion(self) -> bool:
        return self.motion is not None

    @property
    def is_planned(self) -> bool:
        """A collision-free planned joint move."""
        return self.motion == "planned"

    @property
    def is_line(self) -> bool:
        """A straight TCP line (guarded by the wrist force or not)."""
        return self.motion in ("line", "guarded")

    @property
    def is_guarded(self) -> bool:
        """A straight line stopped by the wrist force."""
        return self.motion == "guarded"

    @property
    def label(self) -> str:
        """``step 5 approach 'far_away'``, as messages name a step."""
        return (
            f"step {self.index} {self.kind} {self.name!r}"
            if self.name != self.kind
            else f"step {self.index} {self.kind}"
        )
