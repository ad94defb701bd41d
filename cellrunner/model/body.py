"""What a collision pair, a blocker or a message names: a robot link, the tool, the
carried part, a fixture or a part waiting at its frame, as data.

A :class:`Body` is its own message text ("upper_arm", "tool 'gripper'", "fixture 'table'",
"waiting part 'block'"): it is a ``str`` so the texts built from it read as they always
did, and code asks its :attr:`Body.kind` and :attr:`Body.name` instead of reading the
text back by its prefix.
"""

from __future__ import annotations

from enum import StrEnum

#: prefix of the fixture name of a part waiting at its frame (``part:NAME``)
WAITING_PREFIX = "part:"
#: prefix of the fixture name of a part an earlier step of the job set down
#: (``placed:NAME@STEP``: part NAME let go by step STEP)
PLACED_PREFIX = "placed:"


def is_earlier_slot(fixture_name: str) -> bool:
    """Whether ``fixture_name`` is a part an earlier job left on a pattern's slot
    (``placed:NAME@slotK``, planning/placed.py)."""
    return fixture_name.startswith(PLACED_PREFIX) and "@slot" in fixture_name


class BodyKind(StrEnum):
    """What a :class:`Body` is; the value is the word messages put before its name."""

    ROBOT_LINK = "robot link"  # named bare: "upper_arm"
    TOOL = "tool"
    PART = "part"  # the carried part
    FIXTURE = "fixture"
    WAITING_PART = "waiting part"  # a part waiting at its frame (fixture ``part:NAME``)
    PLACED_PART = "placed part"  # a part set down by the job (fixture ``placed:NAME@STEP``)
    NOTHING = "nothing"  # a scene without pairs: named bare, "robot" and "nothing"


#: the kinds named bare in messages (their name alone)
BARE_KINDS = frozenset({BodyKind.ROBOT_LINK, BodyKind.NOTHING})


#: the kinds that stand still in the cell (a pair's obstacle)
OBSTACLE_KINDS = frozenset({BodyKind.FIXTURE, BodyKind.WAITING_PART, BodyKind.PLACED_PART})
#: the kinds that are parts lying in the cell (a grip there would take them)
LYING_KINDS = frozenset({BodyKind.WAITING_PART, BodyKind.PLACED_PART})


class Body(str):
    """One named body: ``kind`` and ``name`` (a fixture's or part's name as the cell file
    writes it, a link's pinocchio name). Its text is how messages name it."""

    kind: BodyKind
    name: str

    def __new__(cls, kind: BodyKind, name: str) -> Body:
        text = name if kind in BARE_KINDS else f"{kind.value} {name!r}"
        body = super().__new__(cls, text)
        body.kind, body.name = kind, name
        return body

    def __getnewargs__(self) -> tuple[BodyKind, str]:  # type: ignore[override]
        return self.kind, self.name

    def __repr__(self) -> str:
        return f"Body({self.kind.name}, {self.name!r})"

    @classmethod
    def fixture(cls, name: str) -> Body:
        """Fixture ``name`` of the collision scene: a waiting part for ``part:NAME``."""
        if name.startswith(WAITING_PREFIX):
            return cls(BodyKind.WAITING_PART, name[len(WAITING_PREFIX) :])
        if name.startswith(PLACED_PREFIX):
            return cls(BodyKind.PLACED_PART, name[len(PLACED_PREFIX) :])
        return cls(BodyKind.FIXTURE, name)

    @property
    def is_obstacle(self) -> bool:
        """A fixture or a waiting part: it stands still in the cell."""
        return self.kind in OBSTACLE_KINDS

    @property
    def fixture_name(self) -> str:
        """The collision scene's fixture name of an obstacle (``part:NAME`` for a waiting
        part); '' for the robot's bodies."""
        if self.kind is BodyKind.WAITING_PART:
            return WAITING_PREFIX + self.name
        if self.kind is BodyKind.PLACED_PART:
            return PLACED_PREFIX + self.name
        return self.name if self.kind is BodyKind.FIXTURE else ""
