"""What blocks a plan: the links and fixtures in the way, and why each IK branch fails.

Planning stops with an :class:`~cellrunner.errors.InfeasibleError`; this module makes its
message name the cause and a fix, from facts measured in the same collision model:

- :func:`blocking_summary`: over sampled joint states (a failed search's states in
  collision, the gap its best attempt left), which robot part hits which fixture (or
  other link) in how many of them: "forearm vs fixture 'conveyor' in 41 of 60 states".
- :func:`explain_ik_branches`: for a pose, every IK branch and why it is refused: out of
  the joint range (which joint, its value and range), in collision (with what, how deep),
  or near a singularity.
- :func:`fix_hint`: one suggestion from the kind of cause (move the frame, approach from
  another direction, move the fixture or raise it).

The errors carry a :class:`~cellrunner.model.failure.Failure` whose blockers are the
bodies found (``check`` groups failures across slots by kind, step and blockers).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.body import Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind

if TYPE_CHECKING:
    from cellrunner.errors import InfeasibleError
    from cellrunner.planning.collision import Clearance, CollisionModel
    from cellrunner.planning.kinematics import ArmKinematics

#: how many sampled states are measured for a summary (each costs one distance query per pair)
MAX_STATES = 60
#: how many obstacles a summary names, and robot parts per obstacle
MAX_OBSTACLES = 3
MAX_PARTS = 3


@dataclass(frozen=True)
class Blockers:
    """Pairs in the way over ``states`` sampled states, most frequent first:
    ``counts`` is ((robot part, obstacle), number of states) pairs."""

    counts: tuple[tuple[tuple[Body, Body], int], ...]
    states: int
    obstacles: tuple[tuple[Body, int], ...] = ()  # (obstacle, states it blocks), most first

    @property
    def names(self) -> tuple[Body, ...]:
        """Every link and fixture named, most frequent first (no repeats)."""
        out: list[Body] = []
        for (a, b), _ in self.counts:
            for name in (b, a):
                if name not in out:
                    out.append(name)
        return tuple(out)

    @property
    def blockers(self) -> tuple[Blocker, ...]:
        """:attr:`names` as blockers, each with the number of states it is in the way in."""
        states: Counter[Body] = Counter()
        for (a, b), n in self.counts:
            states[a] += n
            states[b] += n
        return tuple(Blocker(body, states=states[body]) for body in self.names)

    def describe(self) -> str:
        """'blocked by fixture 'conveyor' (forearm in 41 of 60 sampled states, wrist_1 in 12)'"""
        return "; ".join(self.clauses())

    def clauses(self) -> list[str]:
        """:meth:`describe` one obstacle a clause."""
        if not self.counts:
            return ["no sampled state in collision was found (the way is too narrow to sample)"]
        by_obstacle: dict[Body, list[tuple[Body, int]]] = {}
        for (part, obstacle), n in self.counts:  # most frequent first, so each list is too
            by_obstacle.setdefault(obstacle, []).append((part, n))
        pieces = []
        for obstacle, parts in list(by_obstacle.items())[:MAX_OBSTACLES]:
            first, *rest = parts[:MAX_PARTS]
            text = f"{first[0]} in {first[1]} of {self.states} sampled states"
            text += "".join(f", {p} in {n}" for p, n in rest)
            pieces.append(f"{obstacle} ({text})")
        return ["blocked by " + pieces[0], *pieces[1:]]


def blocking_summary(
    collision: CollisionModel, q_states: Iterable[np.ndarray], max_states: int = MAX_STATES
) -> Blockers:
    """Count, over up to ``max_states`` of ``q_states`` (evenly picked), the pairs each
    state violates (:meth:`CollisionModel.violations`). A pair is reported as (robot
    part, obstacle): the fixture, or the other link for self-collisions."""
    states = [np.asarray(q, float) for q in q_states]
    if len(states) > max_states:
        states = [states[int(i)] for i in np.linspace(0, len(states) - 1, max_states)]
    counts: Counter[tuple[Body, Body]] = Counter()
    obstacles: Counter[Body] = Counter()
    for q in states:
        pairs = {_ordered(c.a, c.b) for c in collision.violations(q)}
        counts.update(pairs)
        obstacles.update({obstacle for _, obstacle in pairs})
    return Blockers(tuple(counts.most_common()), len(states), tuple(obstacles.most_common()))


def _ordered(a: Body, b: Body) -> tuple[Body, Body]:
    """(robot part, obstacle): a fixture is always the obstacle."""
    if a.is_obstacle:
        return b, a
    return a, b


def line_states(q_from: np.ndarray, q_to: np.ndarray, n: int = 24) -> list[np.ndarray]:
    """``n`` states evenly along the joint-space line (ends excluded)."""
    q0, q1 = np.asarray(q_from, float), np.asarray(q_to, float)
    return [q0 + s * (q1 - q0) for s in np.linspace(0, 1, n + 2)[1:-1]]


# -- IK branches --------------------------------------------------------------------------------


def branch_name(q_rad: np.ndarray) -> str:
    """'elbow up, wrist down (q1 -51 deg)': the branch by the signs of q3 and q5, and the
    base angle that tells the two shoulder branches apart."""
    q = np.asarray(q_rad, float)
    elbow = "elbow up" if math.sin(q[2]) < 0 else "elbow down"
    wrist = "wrist down" if math.sin(q[4]) < 0 else "wrist up"
    return f"{elbow}, {wrist} (q1 {math.degrees(q[0]):.0f} deg)"


def explain_ik_branches(
    kinematics: ArmKinematics,
    collision: CollisionModel,
    T_world_tcp: np.ndarray,
    q_near_rad: np.ndarray,
    *,
    min_singular_deg: float = 0.0,
) -> list[str]:
    """One line per IK branch of ``T_world_tcp`` saying why it cannot be used (empty list:
    no branch at all). Reasons: a joint outside the cell's range (``joint_range`` or the
    controller's), a collision (the pair and depth), a singularity."""
    lines = []
    q_min, q_max = np.degrees(kinematics.q_min_rad), np.degrees(kinematics.q_max_rad)
    for raw in kinematics.ik_raw(T_world_tcp):
        q = kinematics.wrap_near(raw, q_near_rad)
        name = branch_name(raw if q is None else q)
        if q is None:
            deg = np.degrees(np.asarray(raw, float))
            bad = [j for j in range(6) if not _wrappable(deg[j], q_min[j], q_max[j])]
            j = bad[0] if bad else 0
            lines.append(
                f"{name}: joint {j + 1} at {deg[j]:.0f} deg is outside its range "
                f"[{q_min[j]:.0f}, {q_max[j]:.0f}] (joint_range)"
            )
            continue
        hits = collision.violations(q)
        if hits:
            more = f" (+{len(hits) - 1} more)" if len(hits) > 1 else ""
            lines.append(f"{name}: {_short(hits[0])}{more}")
            continue
        if min_singular_deg > 0:
            violation = kinematics.singularity_distance(q).violation(min_singular_deg, 0.0)
            if violation:
                lines.append(f"{name}: {violation}")
                continue
        lines.append(f"{name}: free")
    return lines


def _short(c: Clearance) -> str:
    """'elbow in fixture 'conveyor' 94 mm deep' / 'wrist_1 1.6 mm from fixture 'x' (keeps 2.0)'."""
    if c.distance_m <= 0:
        return f"{c.a} in {c.b} {-c.distance_m * 1000:.1f} mm deep"
    return f"{c.a} {c.distance_m * 1000:.2f} mm from {c.b} (must keep {c.required_m * 1000:.1f})"


def _wrappable(value_deg: float, lo: float, hi: float) -> bool:
    return any(lo - 1e-6 <= value_deg + 360 * k <= hi + 1e-6 for k in (-2, -1, 0, 1, 2))


# -- fixes --------------------------------------------------------------------------------------


def fix_hint(kind: str, obstacles: Sequence[Body] = ()) -> str:
    """A suggestion for a failure ``kind``: "path" (a joint move finds no way), "goal"
    (every branch at the target collides), "line" (a straight move hits something),
    "reach" (out of reach or outside the joint range)."""
    fixtures = [o for o in obstacles if o.is_obstacle]
    links = [o for o in obstacles if o.kind in (BodyKind.ROBOT_LINK, BodyKind.NOTHING)]
    first = fixtures[0] if fixtures else None
    if kind == "reach":
        return "fix: move the frame toward the robot, or widen robot.joint_range if a joint limit refuses it"
    if first is None and links:
        return (
            "fix: the arm folds into itself here; move the frame, or approach from another "
            "direction (offset rpy)"
        )
    if kind == "path":
        return (
            f"fix: move {first or 'the obstacle'} away from the arm's way, raise the approach "
            "(a larger approach distance), or add a move through a free waypoint before this step"
        )
    if kind == "goal":
        return (
            f"fix: move the frame away from {first or 'the obstacle'}, or approach from another "
            "direction (turn the frame's rpy)"
        )
    return (
        f"fix: move the frame or {first or 'the obstacle'} so the straight line keeps its clearance, "
        "or approach from another direction"
    )


# -- the errors ---------------------------------------------------------------------------------


def unreachable(
    label: str,
    kinematics: ArmKinematics,
    collision: CollisionModel,
    T_world_tcp: np.ndarray,
    q_near_rad: np.ndarray,
    approach_m: float | None = None,
) -> InfeasibleError:
    """The error for a pose with no IK branch inside the joint ranges: the reach, or each
    branch and the joint that refuses it. ``approach_m``: the step's approach distance,
    named when it is what puts the pose out of reach (a length written in mm)."""
    from cellrunner.errors import InfeasibleError

    reason, mm_hint = kinematics.unreachable_why(T_world_tcp)
    lines = explain_ik_branches(kinematics, collision, T_world_tcp, q_near_rad)
    details = (f"{len(lines)} branches tried: {lines[0]}", *lines[1:]) if lines else ()
    fix = fix_hint("reach")
    reach_m = kinematics.spec.reach_m
    if mm_hint:
        fix = "fix: write the frame's xyz in metres, or each with its unit ('450 mm')"
    if approach_m is not None and approach_m > reach_m:
        mm_hint = ""  # the approach distance is what was written in mm: the fix says so
        fix = (
            f"the approach distance {approach_m:g} m is longer than the reach: did you mean "
            f"{approach_m:g} mm = {approach_m / 1000:g} m? (write '{approach_m:g} mm')"
        )
    return InfeasibleError(
        Failure(FailureKind.UNREACHABLE, reason + mm_hint, details, fix=fix, step=label)
    )


def every_branch_collides(
    label: str,
    kinematics: ArmKinematics,
    collision: CollisionModel,
    T_world_tcp: np.ndarray,
    q_near_rad: np.ndarray,
) -> InfeasibleError:
    """The error for a pose whose every IK branch collides: each branch and its pair."""
    from cellrunner.errors import InfeasibleError

    lines = explain_ik_branches(kinematics, collision, T_world_tcp, q_near_rad)
    reachable = [
        q
        for q in (kinematics.wrap_near(r, q_near_rad) for r in kinematics.ik_raw(T_world_tcp))
        if q is not None
    ]
    blockers = blocking_summary(collision, reachable)
    obstacle, n = blockers.obstacles[0] if blockers.obstacles else ("an obstacle", 0)
    part = next((p for (p, o), _ in blockers.counts if o == obstacle), "arm")
    reason = f"every IK branch collides, {n} of {len(lines)} with {obstacle} (mostly the {part})"
    return InfeasibleError(
        Failure(
            FailureKind.COLLISION,
            reason,
            tuple(lines),
            blockers.blockers,
            fix_hint("goal", blockers.names),
            step=label,
        )
    )
