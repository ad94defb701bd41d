"""What planning a step leaves: the row ``check`` shows (:class:`StepPlan`), the inputs its
trajectory was verified with, and a motion's joint waypoints before timing (:class:`_Motion`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from cellrunner.model.expand import Step
from cellrunner.model.geometry import Placed
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory

if TYPE_CHECKING:
    from cellrunner.planning.collision import CollisionModel, ContactAllowance
    from cellrunner.planning.timing import MotionLimits
    from cellrunner.planning.world import CellWorld


class VerifyInputs(TypedDict):
    """What verify_trajectory was given besides the trajectory and the step."""

    previous_q_rad: np.ndarray
    previous_moving: bool
    ends_at_rest: bool
    line_m: tuple[np.ndarray, np.ndarray] | None


class _TimedPiece(TypedDict):
    trajectory: Trajectory  # its q_rad is the piece's samples (one copy, kept by the memo)
    approved: ApprovedTrajectory
    inputs: VerifyInputs


@dataclass
class StepPlan:
    """One row of ``check``: the step and, for motions, its approved trajectory."""

    step: Step
    status: str = "ok"  # ok | failed | not planned
    message: str = ""
    duration_s: float = 0.0
    approved: ApprovedTrajectory | None = None
    trajectory: Trajectory | None = None  # what is streamed; sealed in ``approved`` once verified
    q_end_rad: np.ndarray | None = None
    carrying: Placed | None = None
    allowances: tuple[ContactAllowance, ...] = ()
    verify_inputs: VerifyInputs | None = (
        None  # what verify_trajectory was given, to re-verify a cached plan
    )
    world: CellWorld | None = (
        None  # the world (mounted tool) the step was planned in; None: the plan's
    )


@dataclass
class _Motion:
    """A motion step's joint waypoints before timing."""

    row: StepPlan
    waypoints: np.ndarray
    limits: MotionLimits
    line_m: tuple[np.ndarray, np.ndarray] | None
    collision: CollisionModel
    world: CellWorld
    #: for a joint move the planner only sampled: the same move planned with every piece
    #: proven (:func:`_prove_sampled`), for when its timed trajectory fails verification
    proven: Callable[[], np.ndarray] | None = None
    #: what ``proven`` leaves for after it: when ``proven`` is the sampled path with its
    #: via points where the search left them (:attr:`JointPath.loose`), the proven plan
    then_proven: Callable[[], np.ndarray] | None = None
    #: the last resort of a joint move whose proven path still fails verification: the
    #: same move planned proven keeping ``PLAN_MARGIN_M`` more than the verifier asks
    with_margin: Callable[[], np.ndarray] | None = None
