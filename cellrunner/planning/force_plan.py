"""Planning the force steps: their straight line, and the contact they may make.

``move_until_contact`` runs to ``max_distance`` along its direction and ``insert`` to
``depth`` past its frame; ``check`` verifies the whole line. The contact the step is
for is allowed only where the line ends: the carried part (or, carrying nothing, the
tool) may reach into the fixtures it meets at the end of the line, by no more than it
does there; every other pair (the arm, the tool holding a part, other fixtures) keeps the
full clearance.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.body import Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.step import StepKind
from cellrunner.planning.collision import CollisionModel, ContactAllowance

if TYPE_CHECKING:
    from cellrunner.model.force_steps import MoveUntilContactArgs
    from cellrunner.model.geometry import Placed
    from cellrunner.model.step import Step
    from cellrunner.planning.world import CellWorld


class LineStart(Protocol):
    """Where a force step's line starts, as the task's step planner tracks it: the cell,
    the arm's configuration (rad), the part carried, the collision model carrying it."""

    world: CellWorld
    q: np.ndarray
    part: Placed | None

    def collision(self, allowances: tuple[ContactAllowance, ...] = ()) -> CollisionModel: ...


#: contact allowed beyond the depth measured at the line's end (m)
CONTACT_SLACK_M = 0.001
#: a guarded line touches where its mover comes this close to an obstacle (m): the twin's
#: contact, and the controller's, needs the surfaces to meet
TOUCH_M = 1e-4


def contact_line_goal(args: MoveUntilContactArgs, T_world_tcp: np.ndarray) -> np.ndarray:
    """The end of a move_until_contact line from ``T_world_tcp`` (full max_distance)."""
    d = np.asarray(args.direction, float) * args.max_distance
    if args.frame == "tool":
        return np.asarray(T_world_tcp @ geometry.pose_matrix(tuple(d)))
    return np.asarray(geometry.pose_matrix(tuple(d)) @ T_world_tcp)


def contact_allowances(
    planner: LineStart, step: Step, T_goal: np.ndarray
) -> tuple[ContactAllowance, ...]:
    """Allowances for the fixtures the carried part (or, carrying nothing, the tool) meets
    at the line's end, by no more than it reaches into them there."""
    try:
        q_end = planner.world.kinematics.ik_nearest(T_goal, planner.q)
    except Exception:  # unreachable: the line planner says why
        return ()
    # what makes the contact: the carried part, or the tool when nothing is carried (the
    # tool holding a part must keep its clearance, as the arm always does)
    mover, kind = ("part", BodyKind.PART) if planner.part is not None else ("tool", BodyKind.TOOL)
    # while looking for the mover's contacts, the tool's own are left for the line check
    # to report (as the collision it is)
    others = (
        tuple(ContactAllowance(f.name, "tool", -1.0) for f in planner.world.fixtures)
        if mover == "part"
        else ()
    )
    allowances: list[ContactAllowance] = []
    for _ in range(8):  # one pair per round, a line meets few
        model = planner.collision(tuple(allowances) + others)
        clearance = model.clearance(q_end)
        if (
            clearance.distance_m >= clearance.required_m
            or clearance.b.kind is not BodyKind.FIXTURE
            or clearance.a.kind is not kind
        ):
            break
        fixture = clearance.b.name
        allowances.append(
            ContactAllowance(fixture, mover, min(clearance.distance_m, 0.0) - CONTACT_SLACK_M)
        )
    return tuple(allowances)


def describe(
    step: Step,
    line_m: tuple[np.ndarray, np.ndarray] | None,
    allowances: tuple[ContactAllowance, ...],
) -> str:
    """The row message of a force step: its stop force, the line checked, the contact allowed."""
    limit = step.args.force if step.kind == StepKind.MOVE_UNTIL_CONTACT else step.args.force.max
    length_mm = float(np.linalg.norm(line_m[1] - line_m[0])) * 1000 if line_m is not None else 0.0
    where = ", ".join(sorted({a.fixture for a in allowances if a.min_clearance_m < 0})) or "none"
    return f"guarded: stops above {limit:g} N; {length_mm:.0f} mm line checked; contact allowed with: {where}"


def _touch_pairs(
    collision: CollisionModel, carrying: bool, exclude: frozenset[str] = frozenset()
) -> np.ndarray:
    """The pairs whose touch stops a guarded line: the carried part (or, carrying nothing,
    the tool) against a fixture or a waiting part (not one named in ``exclude``)."""
    mover = BodyKind.PART if carrying else BodyKind.TOOL
    return np.array(
        [
            k
            for k, (a, b) in enumerate(collision.pair_labels)
            if a.kind is mover and b.is_obstacle and b.name not in exclude
        ],
        dtype=int,
    )


def _gap_m(collision: CollisionModel, pairs: np.ndarray, q_rad: np.ndarray) -> tuple[float, str]:
    """The smallest distance (m) over ``pairs`` at ``q_rad`` and what it is to."""
    distances, _ = collision.pair_distances(q_rad)
    if not len(pairs):
        return float("inf"), "nothing"
    k = int(pairs[int(np.argmin(distances[pairs]))])
    return float(distances[k]), collision.pair_labels[k][1]


def first_touch(
    collision: CollisionModel,
    q_rad: np.ndarray,
    carrying: bool,
    exclude: frozenset[str] = frozenset(),
) -> np.ndarray | None:
    """Where a guarded line along the joint samples ``q_rad`` (N x 6) first touches (its
    mover within ``TOUCH_M`` of a fixture or waiting part, not one named in ``exclude``),
    located between samples by bisection to 1/1024 of their step; None when it touches
    nothing. ``collision``: the cell's model with the carried part and no allowances."""
    pairs = _touch_pairs(collision, carrying, exclude)
    if not len(pairs):
        return None
    q = np.asarray(q_rad, float)
    if _gap_m(collision, pairs, q[0])[0] <= TOUCH_M:
        return np.array(q[0])
    for a, b in itertools.pairwise(q):
        if _gap_m(collision, pairs, b)[0] > TOUCH_M:
            continue
        lo, hi = 0.0, 1.0
        for _ in range(10):
            mid = 0.5 * (lo + hi)
            if _gap_m(collision, pairs, a + mid * (b - a))[0] > TOUCH_M:
                lo = mid
            else:
                hi = mid
        return np.asarray(a + hi * (b - a))
    return None


def meets_nothing(
    step: Step, collision: CollisionModel, q_end: np.ndarray, carrying: bool
) -> Failure:
    """The failure of a move_until_contact whose line touches nothing the cell file has."""
    gap, nearest = _gap_m(collision, _touch_pairs(collision, carrying), q_end)
    mover = "held part" if carrying else "tool"
    where = (
        f"at its end the {mover} is still {gap * 1000:.1f} mm from {nearest}"
        if np.isfinite(gap)
        else f"the {mover} has nothing to touch"
    )
    longer = (
        f" (at least {(step.args.max_distance + gap) * 1000:.0f} mm)" if np.isfinite(gap) else ""
    )
    return Failure(
        FailureKind.CONTACT,
        f"the guarded line meets nothing within its max_distance "
        f"{step.args.max_distance * 1000:.0f} mm: {where}, so the step would fail with no contact",
        blockers=(Blocker(nearest, gap),) if isinstance(nearest, Body) and np.isfinite(gap) else (),
        fix=f"fix: a longer max_distance{longer}, or move the frame it starts from",
        step_index=step.index,
        step=step.label,
    )
