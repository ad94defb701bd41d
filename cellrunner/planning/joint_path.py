"""Collision-free joint-space paths: the straight joint move when it is free, else OMPL.

The search is OMPL's RRTConnect over the six joint angles (rad), within the joint limits
narrowed to half a turn beyond the start and goal on each joint (so a plan never winds a
joint by a full turn for nothing).

For speed the search samples its edges (every 0.1 rad), the path is shortened by greedy
shortcutting with the same sampled check, its via points are pulled toward their
neighbours' chord (:func:`tighten`, both new edges checked alike), and each corner is
rounded by a short arc where one fits (:func:`round_corners`, so the timed trajectory need
not crawl through it).

Two kinds of path:

- ``proven=True`` (the default): every piece is proven here by
  :meth:`CollisionModel.check_motion` or :meth:`CollisionModel.check_path` (conservative
  advancement, exact up to 0.1 mm), never by sampling alone: the arcs are chosen by proof,
  then the straight pieces left between them are proven. When one fails (an obstacle
  slipped between samples), the searched path is shortened again proving every edge it
  keeps; when the searched path itself fails, the search runs again with the conservative
  check on every edge.
- ``proven=False``: the path is only sampled (the straight move, the arcs and their chords
  every 0.1 rad, like the search), for a caller that proves it anyway. Task planning does:
  the verifier (:mod:`.verify`) proves every timed trajectory before it is approved, and
  proving the same path here first did that work twice. When the proof fails, task
  planning takes the same path with its via points pulled less close
  (:attr:`JointPath.loose`: a via point pulled up to an obstacle brings an edge near it,
  where sampling may miss it), and when that fails too, plans the move again with
  ``proven=True``.

OMPL draws its random numbers from a process-wide generator; each call reseeds it with
``seed`` so that a call's result depends only on its arguments when it is the first OMPL
user in the process (and is reproducible run to run when calls come in the same order).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.planning.collision import CollisionModel
from cellrunner.planning.motion_bounds import bisection_order

#: RRTConnect extension length: largest Euclidean joint-space step per tree extension.
RRT_RANGE_RAD = 1.5
#: Edge sampling step (joint-space distance, rad) of the search and of the shortcutting
#: after it. What the path keeps is proven afterwards, so the sampling only steers: 0.1 rad
#: halves the state checks of 0.05 and was ~10% faster over the planning bench (median 6.1
#: -> 5.4 ms); 0.15-0.2 made the median smaller but the total larger (more fallbacks).
LAZY_RESOLUTION_RAD = 0.1
#: Corner rounding (:func:`round_corners`): fractions of the adjacent edges tried, largest
#: first (half of each edge: neighbouring arcs meet, as PolyScope's largest blend radius at a
#: via point), and the number of points of each arc.
CORNER_FRACTIONS = (0.5, 0.35, 0.2, 0.1)
CORNER_POINTS = 32
#: states in collision a failed search keeps to say what blocked it
MAX_REFUSED_KEPT = 2000
#: Via point tightening (:func:`tighten`): how far each interior waypoint is pulled toward
#: the chord of its neighbours, largest first, and the passes over the path.
TIGHTEN_FRACTIONS = (1.0, 0.5, 0.25)
TIGHTEN_PASSES = 3
#: how much more than the clearance a via point of the loose path keeps (m,
#: :attr:`JointPath.loose`): with it, the planning bench's sampled paths pass the proof as
#: often as unpulled ones (17 of 20), and the UR20 palletizer's approach stays 0.8 s
#: shorter than unpulled
LOOSE_MARGIN_M = 0.02


@dataclass(frozen=True)
class JointPath:
    """Waypoints ``q_rad`` (N x 6, N >= 2) joined by straight joint-space segments;
    ``planner`` is "direct" or "rrtconnect"; ``proven``: every segment proven collision-free
    (else sampled only, module docstring)."""

    q_rad: np.ndarray
    planner: str
    planning_time_s: float
    proven: bool = True
    #: a sampled path whose via points were pulled in (:func:`tighten`): the same path
    #: with them pulled only where they keep ``LOOSE_MARGIN_M`` more than the clearance,
    #: for a caller whose proof of ``q_rad`` fails (a via point pulled up to an obstacle
    #: brings an edge near it, where sampling may miss it): cheaper to prove than planning
    #: the move proven
    loose: Callable[[], np.ndarray] | None = None


def plan_joint_path(
    collision: CollisionModel,
    q_start_rad: np.ndarray,
    q_goal_rad: np.ndarray,
    *,
    time_budget_s: float = 2.0,
    seed: int = 1,
    proven: bool = True,
) -> JointPath:
    """A collision-free path from ``q_start_rad`` to ``q_goal_rad`` (both (6,), rad);
    with ``proven=False`` only sampled, for a caller that proves it (module docstring).

    Raises :class:`InfeasibleError` when the start or goal is in collision or outside the
    joint limits, or when no path is found within ``time_budget_s``.
    """
    t0 = time.perf_counter()
    q0 = np.asarray(q_start_rad, float)
    q1 = np.asarray(q_goal_rad, float)
    kin = collision.kinematics
    for label, q in (("start", q0), ("goal", q1)):
        if not kin.within_limits(q):
            raise InfeasibleError(
                Failure(
                    FailureKind.LIMITS, f"{label} configuration outside the joint limits: {_deg(q)}"
                )
            )
        if not collision.is_valid(q):
            c = collision.clearance(q)
            raise InfeasibleError(
                Failure(
                    FailureKind.COLLISION,
                    f"{label} configuration in collision: {c.describe()}",
                    blockers=(Blocker(c.b, c.distance_m), Blocker(c.a, c.distance_m)),
                )
            )
    if (
        collision.check_motion(q0, q1, explain=False).ok
        if proven
        else sampled_free(collision, q0, q1)
    ):
        return JointPath(np.array([q0, q1]), "direct", time.perf_counter() - t0, proven)
    deadline = t0 + time_budget_s
    lazy = _rrt_connect(collision, q0, q1, time_budget_s, seed, conservative=False)
    if not proven:
        sampled = _shorten_and_round(collision, lazy, _sampled_polyline_free)[0]
        loose = functools.partial(_loose, collision, lazy)
        return JointPath(sampled, "rrtconnect", time.perf_counter() - t0, False, loose)
    # Fast pass: search and shorten with sampled edge checks, round the corners with proven
    # arcs, then prove the straight pieces left between the arcs. When one fails its proof
    # (an obstacle slipped between samples), shorten again proving every edge; when the
    # searched path itself fails, search again with the conservative check on every edge.
    path = _shorten_sampled_then_prove(collision, lazy)
    if path is None:
        certified = shortcut(collision, lazy, edges_checked=False, direct_blocked=True)
        if certified is None:
            remaining = max(deadline - time.perf_counter(), 0.1 * time_budget_s)
            strict = _rrt_connect(collision, q0, q1, remaining, seed + 1, conservative=True)
            certified = shortcut(collision, strict, edges_checked=True)
            assert certified is not None  # with every edge checked, shortcut refuses nothing
        path = round_corners(collision, tighten(collision, certified, proven_free))
    return JointPath(path, "rrtconnect", time.perf_counter() - t0)


def _shorten_sampled_then_prove(collision: CollisionModel, lazy: np.ndarray) -> np.ndarray | None:
    """The searched path shortened with sampled checks (:func:`sampled_free`), its corners
    rounded by proven arcs, and every straight piece left between them proven; None when
    one of those fails its proof. Most of a shortened edge ends up inside the arcs (half of
    each edge at the largest fraction), so this proves about half the straight length that
    proving every shortened edge would, and the sampled shortcut tries cost a fraction of
    proofs."""
    path, straight = _shorten_and_round(collision, lazy, _proven_polyline_free)
    for i in straight:
        a, b = path[i], path[i + 1]
        if (
            not np.array_equal(a, b)
            and not collision.check_motion(a, b, explain=False, probe=False).ok
        ):
            return None
    return path


def _shorten_and_round(
    collision: CollisionModel,
    lazy: np.ndarray,
    arc_free: Callable[[CollisionModel, np.ndarray], bool],
    margin_m: float = 0.0,
) -> tuple[np.ndarray, list[int]]:
    """The searched path shortened with sampled checks, its via points pulled in (keeping
    ``margin_m`` more than the clearance), then :func:`_with_corner_arcs` with arcs that
    ``arc_free`` accepts."""
    short = shortcut(collision, lazy, direct_blocked=True, free=sampled_free)
    assert short is not None  # the searched edges are taken as sampled: nothing refused
    return _with_corner_arcs(collision, tighten(collision, short, sampled_free, margin_m), arc_free)


def _loose(collision: CollisionModel, lazy: np.ndarray) -> np.ndarray:
    """The sampled path of the search ``lazy`` with its via points pulled only where they
    keep ``LOOSE_MARGIN_M`` (:attr:`JointPath.loose`)."""
    return _shorten_and_round(collision, lazy, _sampled_polyline_free, LOOSE_MARGIN_M)[0]


def proven_free(collision: CollisionModel, qa: np.ndarray, qb: np.ndarray) -> bool:
    """Whether the straight move qa -> qb is proven free (:meth:`CollisionModel.check_motion`)."""
    return collision.check_motion(qa, qb, explain=False).ok


def tighten(
    collision: CollisionModel,
    q_rad: np.ndarray,
    free: Callable[[CollisionModel, np.ndarray, np.ndarray], bool],
    margin_m: float = 0.0,
) -> np.ndarray:
    """The path with each interior waypoint w (between a and b) pulled toward the point
    of the chord a -> b nearest to it, by the largest of ``TIGHTEN_FRACTIONS`` for which
    ``free`` accepts both new edges (and the pulled point keeps ``margin_m`` more than
    the clearance); a few passes, since each pull opens room for its
    neighbours'. Shortcutting keeps only waypoints of the searched path, whose corners
    sit where the search happened to sample; pulling them in shortens the path (the
    demo's cycle by 6 %) and never lengthens it (triangle inequality)."""
    q = np.array(q_rad, float)
    for _ in range(TIGHTEN_PASSES):
        moved = False
        for i in range(1, len(q) - 1):
            a, w, b = q[i - 1], q[i], q[i + 1]
            chord = b - a
            s = float(np.dot(w - a, chord) / max(float(np.dot(chord, chord)), 1e-18))
            c = a + min(max(s, 0.0), 1.0) * chord
            if float(np.linalg.norm(c - w)) < 1e-4:
                continue
            for f in TIGHTEN_FRACTIONS:
                p = w + f * (c - w)
                if (
                    _roomy(collision, p, margin_m)
                    and free(collision, a, p)
                    and free(collision, p, b)
                ):
                    q[i] = p
                    moved = True
                    break
        if not moved:
            break
    return q


def _roomy(collision: CollisionModel, q: np.ndarray, margin_m: float) -> bool:
    """Whether every pair keeps ``margin_m`` more than its clearance at ``q``."""
    if margin_m <= 0.0:
        return True
    c = collision.clearance(q)
    return c.distance_m - c.required_m >= margin_m


def sampled_free(collision: CollisionModel, qa: np.ndarray, qb: np.ndarray) -> bool:
    """Whether the states every ``LAZY_RESOLUTION_RAD`` (joint-space distance) along qa -> qb
    are free, checked coarse to fine (the search's own edge check; it proves nothing)."""
    n = max(1, math.ceil(float(np.linalg.norm(qb - qa)) / LAZY_RESOLUTION_RAD))
    return all(collision.is_valid(qa + s * (qb - qa)) for s in bisection_order(n))


def _sampled_polyline_free(collision: CollisionModel, q: np.ndarray) -> bool:
    """Whether every point of the polyline ``q`` and the states every
    ``LAZY_RESOLUTION_RAD`` along its longer chords are free (sampled; it proves nothing)."""
    long = np.nonzero(np.linalg.norm(np.diff(q, axis=0), axis=1) > LAZY_RESOLUTION_RAD)[0]
    return all(collision.is_valid(p) for p in q) and all(
        sampled_free(collision, q[i], q[i + 1]) for i in long
    )


def _proven_polyline_free(collision: CollisionModel, q: np.ndarray) -> bool:
    return collision.check_path(q).ok


def round_corners(collision: CollisionModel, q_rad: np.ndarray) -> np.ndarray:
    """The path with each interior waypoint w (between a and b) replaced by a quadratic
    Bezier arc from w + f (a - w) to w + f (b - w) with control point w, sampled at
    ``CORNER_POINTS`` points, for the largest f of ``CORNER_FRACTIONS`` whose arc passes
    :meth:`CollisionModel.check_path`; corners no arc clears stay. The straight pieces
    before and after an arc are parts of the path's edges, proven by the caller. A sharp
    corner in joint space forces the time parameterization to crawl through it; the arc
    lets it keep moving."""
    return _with_corner_arcs(collision, q_rad)[0]


def _with_corner_arcs(
    collision: CollisionModel,
    q_rad: np.ndarray,
    arc_free: Callable[[CollisionModel, np.ndarray], bool] = _proven_polyline_free,
) -> tuple[np.ndarray, list[int]]:
    """:func:`round_corners` and the indices i whose piece i -> i + 1 is straight (not
    inside an arc); ``arc_free`` accepts an arc (default: proven)."""
    q = np.asarray(q_rad, float)
    if len(q) < 3:
        return q, list(range(len(q) - 1))
    out = [q[0]]
    straight = []
    t = np.linspace(0.0, 1.0, CORNER_POINTS)[:, None]
    for a, w, b in zip(q[:-2], q[1:-1], q[2:], strict=True):
        arc = None
        for f in CORNER_FRACTIONS:
            p1, p2 = w + f * (a - w), w + f * (b - w)
            if np.abs(p1 - out[-1]).max() < 1e-12:
                p1 = out[-1]  # where the arc before ends (to the last bit): no piece between
            candidate = (1 - t) ** 2 * p1 + 2 * (1 - t) * t * w + t**2 * p2
            if arc_free(collision, candidate):
                arc = candidate
                break
        straight.append(len(out) - 1)
        out.extend(arc if arc is not None else [w])
    straight.append(len(out) - 1)
    out.append(q[-1])
    return np.array(out), straight


def shortcut(
    collision: CollisionModel,
    q_rad: np.ndarray,
    *,
    edges_checked: bool = True,
    direct_blocked: bool = False,
    free: Callable[[CollisionModel, np.ndarray, np.ndarray], bool] | None = None,
) -> np.ndarray | None:
    """Greedy shortcutting: from each kept waypoint, jump to the farthest later waypoint
    reachable by a straight segment that ``free`` accepts (default: proven by
    :meth:`CollisionModel.check_motion`). Deterministic; never lengthens the path. With
    ``edges_checked=False`` the path's own edges are not yet proven either (they were
    sampled finely, so their proof skips the coarse probes); returns None when one of them
    fails. ``direct_blocked``: the first-to-last segment is already known to be blocked."""
    q = np.asarray(q_rad, float)
    kept = [0]
    i = 0
    while i < len(q) - 1:
        for j in range(len(q) - 1, i, -1):
            if direct_blocked and i == 0 and j == len(q) - 1 and j > 1:
                continue
            edge = j == i + 1
            if edge and (edges_checked or free is not None):
                ok = True
            elif free is not None:
                ok = free(collision, q[i], q[j])
            else:
                ok = collision.check_motion(q[i], q[j], explain=False, probe=not edge).ok
            if ok:
                kept.append(j)
                i = j
                break
        else:
            return None
    return q[kept]


def ompl_problem(
    collision: CollisionModel, q0: np.ndarray, q1: np.ndarray, seed: int
) -> tuple[Any, Any, Any, Callable[[Any], np.ndarray]]:
    """An OMPL problem from ``q0`` to ``q1`` in the arm's joint space, each joint within
    its limits and within pi beyond both ends, OMPL's generator seeded with ``seed``:
    (SimpleSetup, its space information, the space, an OMPL state as an array). The
    caller gives it a validity checker and a planner."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(seed)
    kin = collision.kinematics
    space = ob.RealVectorStateSpace(6)
    bounds = ob.RealVectorBounds(6)
    for i in range(6):
        bounds.setLow(i, float(max(kin.q_min_rad[i], min(q0[i], q1[i]) - math.pi)))
        bounds.setHigh(i, float(min(kin.q_max_rad[i], max(q0[i], q1[i]) + math.pi)))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    start, goal = space.allocState(), space.allocState()
    for i in range(6):
        start[i], goal[i] = float(q0[i]), float(q1[i])
    setup.setStartAndGoalStates(start, goal)

    def as_array(state: Any) -> np.ndarray:  # an OMPL state
        return np.array([state[0], state[1], state[2], state[3], state[4], state[5]])

    return setup, setup.getSpaceInformation(), space, as_array


def _rrt_connect(
    collision: CollisionModel,
    q0: np.ndarray,
    q1: np.ndarray,
    time_budget_s: float,
    seed: int,
    *,
    conservative: bool,
) -> np.ndarray:
    """RRTConnect from q0 to q1. ``conservative``: every edge proven by check_motion;
    otherwise edges are sampled every ``LAZY_RESOLUTION_RAD`` (to be certified after)."""
    from ompl import base as ob
    from ompl import geometric as og

    setup, si, space, as_array = ompl_problem(collision, q0, q1, seed)
    in_collision: list[np.ndarray] = []  # a bounded sample of the refused states, for the message

    def valid(state: Any) -> bool:
        q = as_array(state)
        ok = collision.is_valid(q)
        if not ok and len(in_collision) < MAX_REFUSED_KEPT:
            in_collision.append(q)
        return ok

    setup.setStateValidityChecker(valid)

    class ConservativeMotionValidator(ob.MotionValidator):  # type: ignore[misc]  # OMPL is untyped
        def checkMotion(self, a: Any, b: Any) -> bool:  # OMPL's name
            return collision.check_motion(as_array(a), as_array(b), explain=False).ok

    if conservative:
        si.setMotionValidator(ConservativeMotionValidator(si))
    else:
        si.setStateValidityCheckingResolution(LAZY_RESOLUTION_RAD / space.getMaximumExtent())
    planner = og.RRTConnect(si)
    planner.setRange(RRT_RANGE_RAD)
    setup.setPlanner(planner)
    try:
        # the time limit as a condition the planner polls: solve(seconds) checks it from a
        # thread of its own, started and joined every call (0.3 ms of a 2 ms plan)
        status = setup.solve(ob.timedPlannerTerminationCondition(time_budget_s))
        solved = setup.haveExactSolutionPath()
        best = (
            np.array([as_array(s) for s in setup.getSolutionPath().getStates()])
            if setup.haveSolutionPath()
            else None
        )
    finally:
        # break the Python <-> C++ reference cycles so nothing outlives the call
        setup.setStateValidityChecker(ob.AllValidStateValidityChecker(si))
    if not solved:
        raise _no_path(
            collision,
            q0,
            q1,
            best,
            in_collision,
            f"within {time_budget_s:.1f} s (RRTConnect: {status})",
        )
    assert best is not None  # an exact solution has a path
    path = best
    path[0], path[-1] = q0, q1
    return path


def _no_path(
    collision: CollisionModel,
    q0: np.ndarray,
    q1: np.ndarray,
    best: np.ndarray | None,
    refused: list[np.ndarray],
    how: str,
) -> InfeasibleError:
    """The error of a failed search, naming what blocks it: the pairs in collision along
    the gap between the best attempt's nearest state and the goal (or the straight move
    when there was none), and in the states the search refused."""
    from cellrunner.planning.blockers import blocking_summary, fix_hint, line_states

    near = (
        q0 if best is None or not len(best) else best[np.argmin(np.linalg.norm(best - q1, axis=1))]
    )
    gap = line_states(near, q1)
    blockers = blocking_summary(collision, gap + refused[:: max(1, len(refused) // 36)])
    first, *rest = blockers.clauses()
    return InfeasibleError(
        Failure(
            FailureKind.COLLISION,
            f"no collision-free joint path found {how}: {first}",
            (*rest, f"start {_deg(q0)}, goal {_deg(q1)}"),
            blockers.blockers,
            fix_hint("path", blockers.names),
        )
    )


def _deg(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.1f}" for v in np.degrees(q)) + "] deg"
