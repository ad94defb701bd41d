"""The run-time approval of a tracked stretch (SPEC section 13): the one case the belt's
measured speed and the latched part make, at the controller rate, checked by the very
proof ``check`` runs for every case (:func:`.tracking.tracked_joint_path`: reach, joint
and TCP limits x margin, collisions against the still cell) and sealed only when it
passes. Nothing else of a tracked stretch ever reaches a backend.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory, approve
from cellrunner.planning.belt_ramp import ramp_bounds, ramp_in
from cellrunner.planning.tracked_piece import TrackedPiece, still_piece, tracked_stretches
from cellrunner.planning.tracking import tracked_joint_path

if TYPE_CHECKING:
    from cellrunner.model.conveyor import Conveyor
    from cellrunner.planning.task_plan import TaskPlan


@dataclass(frozen=True)
class TrackedRun:
    """An approved tracked stretch: set-points every 1 / rate, the ramp onto the part
    first (``ramp_in_n`` set-points), then the tracked steps: each step's index and its
    [first, end) set-points (``spans``), then the ramp back. ``start_m`` and
    ``speed_mps``: the part's offset from the frame (m) at the first set-point and the
    belt speed the stretch was made for."""

    approved: ApprovedTrajectory
    ramp_in_n: int
    spans: tuple[tuple[int, int, int], ...]  # (step index, first, end)
    start_m: float
    speed_mps: float
    untrack_index: int


def stretch_piece(plan: TaskPlan, track_index: int, rate_hz: float) -> TrackedPiece | None:
    """The still plan of the stretch whose ``track`` is step ``track_index``, a sample
    every controller period; None when the plan has no such stretch."""
    for _, rows in tracked_stretches(plan):
        if rows[0].step.index == track_index:
            return still_piece(plan.world, plan, rows, 1.0 / rate_hz)
    return None


def approve_tracked(
    plan: TaskPlan,
    track_index: int,
    conveyor: Conveyor,
    piece: TrackedPiece,
    speed_mps: float,
    start_m: float,
) -> TrackedRun | str:
    """The stretch for a part ``start_m`` from the frame moving at ``speed_mps``, approved;
    or why it is refused (the proof's reason)."""
    q, failed = tracked_joint_path(plan.world, conveyor, piece, speed_mps, start_m)
    if failed is not None:
        return failed
    dt = piece.sample_s
    rows = next(r for _, r in tracked_stretches(plan) if r[0].step.index == track_index)
    n_in = max(
        1, int(np.ceil(ramp_in(start_m, speed_mps, ramp_bounds(conveyor.path)).duration_s / dt))
    )
    spans = tuple(
        (row.step.index, n_in + a, n_in + b)
        for row, (a, b) in zip(rows[1:-1], piece.runs, strict=True)
    )
    trajectory = Trajectory(1.0 / dt, np.arange(len(q)) * dt, q)
    return TrackedRun(
        approve(trajectory, track_index, "track"),
        n_in,
        spans,
        start_m,
        speed_mps,
        rows[-1].step.index,
    )
