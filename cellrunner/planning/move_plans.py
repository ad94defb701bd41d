"""A joint move's plans, from the quickest to the surest: sampled (verification proves
the timed trajectory), then with every piece proven when the timed trajectory fails
verification (:func:`_prove_sampled`), then proven keeping ``PLAN_MARGIN_M`` more than the
verifier asks (:func:`_plan_with_margin`), before a refusal stands."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.planning.step_plan import _Motion

if TYPE_CHECKING:
    from cellrunner.planning.collision import CollisionModel


#: what a joint move whose proven path fails verification by a hair is planned keeping
#: beyond the verifier's clearance (m), before the refusal stands (:func:`_plan_with_margin`)
PLAN_MARGIN_M = 0.5e-3


def _sampled_joint_path(
    collision: CollisionModel, head: np.ndarray, goal_q: np.ndarray
) -> tuple[np.ndarray, Callable[[], np.ndarray] | None]:
    """``head`` then a sampled joint path from its end to ``goal_q`` (:func:`_joint_path`),
    and the same with the path's via points where the search left them, if they were
    pulled in (:attr:`JointPath.loose`)."""
    from cellrunner.planning.joint_path import plan_joint_path

    found = plan_joint_path(collision, head[-1], goal_q, proven=False)
    path = np.vstack([head, found.q_rad[1:]])
    loose = found.loose
    if loose is None:
        return path, None
    return path, lambda: np.vstack([head, loose()[1:]])


def _joint_path(
    collision: CollisionModel, head: np.ndarray, goal_q: np.ndarray, *, proven: bool
) -> np.ndarray:
    """``head`` (the start, or the egress line that leaves it), then a joint path from its
    end to ``goal_q``."""
    from cellrunner.planning.joint_path import plan_joint_path

    return np.vstack([head, plan_joint_path(collision, head[-1], goal_q, proven=proven).q_rad[1:]])


def _joint_path_with_margin(
    collision: CollisionModel, head: np.ndarray, goal_q: np.ndarray
) -> np.ndarray:
    """:func:`_joint_path`, proven, keeping ``PLAN_MARGIN_M`` beyond ``collision``'s
    clearance (the model built only when a move needs it)."""
    wider = collision.keeping(collision.clearance_m + PLAN_MARGIN_M)
    return _joint_path(wider, head, goal_q, proven=True)


def _prove_sampled(motion: _Motion) -> bool:
    """Replace ``motion``'s path, when the planner only sampled it, by the same move
    planned with every piece proven; whether it was sampled. Sampling misses an obstacle
    that slips between its samples (3 of the 20 planning-bench problems); the verifier's
    proof of the timed trajectory finds it, and this plans that move the slower way."""
    if motion.proven is None:
        return _plan_with_margin(motion)
    # the motion may be the one the world's memo keeps (:meth:`StepPlanner.motion`): it
    # keeps the proven path, and the jobs that plan the same move again take that
    try:
        motion.waypoints, motion.proven = motion.proven(), motion.then_proven
        motion.then_proven = None
    except InfeasibleError as exc:
        step = motion.row.step
        raise InfeasibleError(
            replace(exc.failure, step_index=step.index, step=step.label)
        ) from None
    return True


def _plan_with_margin(motion: _Motion) -> bool:
    """Replace ``motion``'s proven path, which its timed trajectory still fails by a hair
    (the timing's curve leaves the proven corners by micrometres: a UR10e's carried part
    came 2.094 mm from a shelf against 2.1), by the same move planned keeping
    ``PLAN_MARGIN_M`` more; whether there was such a plan. One clearance rule: the
    verifier still asks what it always asks, the planner leaves itself room for it."""
    with_margin, motion.with_margin = motion.with_margin, None
    if with_margin is None:
        return False
    try:
        motion.waypoints = with_margin()
    except InfeasibleError:
        return False  # no path with the margin: the verifier's refusal stands
    return True
