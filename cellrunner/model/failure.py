"""Why a step cannot be planned, as data: its kind, the step, what blocked it (bodies and
their distances) and the fix.

The planner raises :class:`~cellrunner.errors.InfeasibleError` carrying one
:class:`Failure`; the plan keeps it, ``check`` groups failures by their
:meth:`Failure.key` (kind, step, blockers) and prints, writes JSON or journals them
through :meth:`Failure.text` and :meth:`Failure.lines`: the text is made there, at the
edge, and nothing reads it back.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

from cellrunner.model.body import Body, BodyKind


class FailureKind(StrEnum):
    """What kind of refusal a :class:`Failure` is (the ``kind`` of ``check --json``'s
    failures)."""

    UNREACHABLE = (
        "unreachable"  # no IK branch inside the joint ranges, a line leaving the workspace
    )
    COLLISION = "collision"  # every branch, the joint path or the straight line meets something
    SINGULARITY = "singularity"  # a straight line near a singularity, or needing a branch flip
    LIMITS = "limits"  # a joint's range, speed or acceleration, the TCP cap, the timing
    TRAJECTORY = "trajectory"  # a trajectory off the controller's grid, discontinuous or bent
    SUPPORT = "support"  # a part let go over nothing, or set down into what is under it
    GRIP = "grip"  # the open jaws narrower than the part
    HOLD = "hold"  # cups or jaws that cannot hold the part through the moves that carry it
    CONTACT = "contact"  # a force step that would meet nothing, or an insert stopped short
    JAM = "jam"  # a part pressed into a fixture it may only touch (a rim, an interference fit)
    CAMERA_VIEW = "camera_view"  # a camera that cannot see its zone or its whole marker, or reads it too noisily
    MARKER = "marker"  # an align's marker off the surface of what carries it, or carried by nothing
    MODEL = "model"  # the robot model or the collision scene cannot be built


@dataclass(frozen=True)
class Blocker:
    """A body in the way: its signed distance (m, negative inside) where measured, and in
    how many sampled states it blocks (0: not sampled)."""

    body: Body
    distance_m: float | None = None
    states: int = 0


@dataclass(frozen=True)
class Failure:
    """One refusal. ``reason`` says what is wrong with numbers (no step name, no fix);
    ``details`` are its supporting clauses (each IK branch, each blocker's share), shown
    one per line; ``fix`` the suggestion; ``step`` the step's name as messages write it
    (``step 3 approach 'pick'``, ``on_error`` in front of an on_error step), '' until the
    planner knows it; ``step_index`` 1-based."""

    kind: FailureKind
    reason: str
    details: tuple[str, ...] = ()
    blockers: tuple[Blocker, ...] = ()
    fix: str = ""
    step_index: int | None = None
    step: str = ""

    @property
    def bodies(self) -> tuple[Body, ...]:
        """The blocking bodies, most in the way first."""
        return tuple(b.body for b in self.blockers)

    def key(self) -> tuple[object, ...]:
        """What two failures must share to be the same failure (``check`` groups slots by
        it): kind, step and the bodies in the way, never the text."""
        bodies = frozenset((b.kind, b.name) for b in self.bodies)
        return (self.kind, self.step_index, bodies)

    def at_step(self, index: int, step: str) -> Failure:
        """This failure about step ``index`` named ``step``, if it names no step yet."""
        if self.step_index is not None and self.step:
            return self
        return replace(
            self,
            step_index=index if self.step_index is None else self.step_index,
            step=self.step or step,
        )

    def lines(self) -> list[str]:
        """The failure one clause per line: the step and reason first, then each detail,
        then the fix."""
        head = f"{self.step}: {self.reason}" if self.step else self.reason
        return [head, *self.details, *([self.fix] if self.fix else [])]

    def text(self) -> str:
        """The failure on one line, as messages and the journal write it."""
        return "; ".join(self.lines())

    def summary(self) -> str:
        """The reason and its details without the step's name (a table row's message)."""
        return "; ".join([self.reason, *self.details, *([self.fix] if self.fix else [])])

    def blockers_text(self) -> str:
        """The blockers on one line, most in the way first, each with its distance in mm
        where measured: ``fixture 'table' -4.0 mm, upper_arm``."""
        return ", ".join(
            str(b.body) if b.distance_m is None else f"{b.body} {b.distance_m * 1000:+.1f} mm"
            for b in self.blockers
        )

    def brief(self) -> str:
        """Kind, step and blockers on one short line (a journal listing's column):
        ``collision at step 3: fixture 'table' -4.0 mm``."""
        where = f" at step {self.step_index}" if self.step_index is not None else ""
        blockers = self.blockers_text()
        return f"{self.kind.value}{where}: {blockers}" if blockers else f"{self.kind.value}{where}"

    def to_json(self) -> dict[str, object]:
        """The failure as JSON data (the plan files keep it; :meth:`from_json` reads it)."""
        return {
            "kind": self.kind.value,
            "reason": self.reason,
            "details": list(self.details),
            "blockers": [
                {
                    "kind": b.body.kind.value,
                    "name": b.body.name,
                    "distance_m": b.distance_m,
                    "states": b.states,
                }
                for b in self.blockers
            ],
            "fix": self.fix,
            "step_index": self.step_index,
            "step": self.step,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Failure:
        """The failure :meth:`to_json` wrote (KeyError or ValueError when it is not one)."""
        return cls(
            FailureKind(data["kind"]),
            str(data["reason"]),
            tuple(str(d) for d in data["details"]),
            tuple(
                Blocker(
                    Body(BodyKind(b["kind"]), str(b["name"])), b["distance_m"], int(b["states"])
                )
                for b in data["blockers"]
            ),
            str(data["fix"]),
            data["step_index"],
            str(data["step"]),
        )
