"""The tracked steps of a plan as the arm runs them on a belt (SPEC section 13): the
stretch from ``track`` to ``untrack``, its still plan on one timeline
(:class:`TrackedPiece`), and the belt offset added to it (:func:`commanded_offsets`)::

    T_world_tcp(t) = T_shift(sigma(t)) @ T_world_tcp_still(t)

:mod:`.tracking` proves it for every belt speed and start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.conveyor import Conveyor
from cellrunner.planning.belt_ramp import Ramp, ramp_bounds, ramp_in, ramp_out

if TYPE_CHECKING:
    from cellrunner.model.geometry import Placed
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.task_plan import StepPlan, TaskPlan
    from cellrunner.planning.world import CellWorld


@dataclass(frozen=True)
class TrackedPiece:
    """The still plan of the tracked steps: joint samples every ``sample_s`` s, the TCP
    pose of each, and the collision model (part carried, contacts allowed) of each."""

    q_rad: np.ndarray  # (N, 6)
    T_world_tcp: np.ndarray  # (N, 4, 4)
    models: tuple[CollisionModel, ...]  # per sample run (see ``runs``)
    runs: tuple[tuple[int, int], ...]  # [start, end) sample ranges of each model
    grip_index: int  # the sample where the part is taken or set down (its reach is measured there)
    what: str = "pick"  # a pick (a grip among the steps) or a place onto the belt
    sample_s: float = 0.008  # the period of the samples, s

    @property
    def duration_s(self) -> float:
        return len(self.q_rad) * self.sample_s


def tracked_stretches(plan: TaskPlan) -> list[tuple[str, list[StepPlan]]]:
    """(conveyor, the rows from ``track`` to its ``untrack``, both included) of a plan."""
    out: list[tuple[str, list[StepPlan]]] = []
    open_at: int | None = None
    for i, row in enumerate(plan.rows):
        if row.step.kind == "track":
            open_at = i
        elif row.step.kind == "untrack" and open_at is not None:
            out.append((plan.rows[open_at].step.args.conveyor, plan.rows[open_at : i + 1]))
            open_at = None
    return out


def still_piece(
    world: CellWorld, plan: TaskPlan, rows: list[StepPlan], sample_s: float
) -> TrackedPiece:
    """The tracked steps (between the ``track`` and ``untrack`` rows) as planned for the
    still part, on one timeline resampled every ``sample_s`` s (a motion's set-points by
    linear interpolation, a step that does not move holding its pose)."""
    from cellrunner.planning.collision import CollisionModel

    base = CollisionModel(world.kinematics, world.tool, world.fixtures)
    q = _q_before(plan, rows[0])
    part = _carried_before(plan, rows[0])
    times: list[np.ndarray] = [np.zeros(1)]
    points: list[np.ndarray] = [q[None, :]]
    bounds: list[tuple[float, float]] = []
    models: list[CollisionModel] = []
    t0, t_grip = 0.0, None
    standing: tuple[Any, ...] = ()  # the contacts of the last motion, held while standing
    for row in rows[1:-1]:
        if row.trajectory is not None:
            traj = row.trajectory
            times.append(t0 + np.asarray(traj.t_s[1:], float) - float(traj.t_s[0]))
            points.append(np.asarray(traj.q_rad[1:], float))
            q = np.asarray(traj.q_rad[-1], float)
            t1 = t0 + float(traj.t_s[-1] - traj.t_s[0])
        else:
            t1 = t0 + float(row.duration_s)
            times.append(np.array([t1]))
            points.append(q[None, :])
        if row.step.kind == "grip" and t_grip is None:
            t_grip = t0
        if row.step.is_motion:
            standing = tuple(row.allowances)
        models.append(base.carrying(part).allowing(*(row.allowances or standing)))
        if not row.step.is_motion:
            part = row.carrying
        bounds.append((t0, t1))
        t0 = t1
    t_all, q_src = np.concatenate(times), np.concatenate(points)
    n = max(1, math.ceil(t0 / sample_s) + 1)
    t_grid = np.minimum(np.arange(n) * sample_s, t0)
    q_all = np.column_stack([np.interp(t_grid, t_all, q_src[:, j]) for j in range(6)])
    runs = [(math.floor(a / sample_s), min(n, math.ceil(b / sample_s) + 1)) for a, b in bounds] or [
        (0, n)
    ]
    if not models:
        models = [base.carrying(part)]
    T_all = np.array([world.kinematics.T_world_tcp(qk) for qk in q_all])
    if t_grip is not None:
        grip = min(n - 1, round(t_grip / sample_s))
        return TrackedPiece(q_all, T_all, tuple(models), tuple(runs), grip, sample_s=sample_s)
    # no grip: a place onto the belt, whose lowest pose sets the part down
    lowest = int(np.argmin(T_all[:, 2, 3]))
    return TrackedPiece(
        q_all, T_all, tuple(models), tuple(runs), lowest, what="place", sample_s=sample_s
    )


def _q_before(plan: TaskPlan, row: StepPlan) -> np.ndarray:
    q = np.asarray(plan.q_start_rad, float)
    for r in plan.rows:
        if r is row:
            break
        if r.trajectory is not None:
            q = np.asarray(r.trajectory.q_rad[-1], float)
    return q


def _carried_before(plan: TaskPlan, row: StepPlan) -> Placed | None:
    part = None
    for r in plan.rows:
        if r is row:
            break
        if not r.step.is_motion:
            part = r.carrying
    return part


def commanded_offsets(
    piece: TrackedPiece, conveyor: Conveyor, speed_mps: float, start_m: float
) -> tuple[np.ndarray, np.ndarray, Ramp, Ramp]:
    """(sigma m at every sample, the still sample each one holds, the ramp in, the ramp
    out) of one case, on the piece's grid of samples: the ramp onto the part (the arm
    holding its pose at ``track``; past the ramp's end the part's own travel), the steps
    with the part's travel, the ramp back (holding the pose at ``untrack``)."""
    dt = piece.sample_s
    bounds = ramp_bounds(conveyor.path)
    r_in = ramp_in(start_m, speed_mps, bounds)
    n_in = max(1, math.ceil(r_in.duration_s / dt))
    t_in = np.arange(n_in) * dt
    s_ramp, _, _ = r_in.at(t_in)
    s_in = np.where(t_in <= r_in.duration_s, s_ramp, start_m + speed_mps * t_in)
    n = len(piece.q_rad)
    t_follow = (n_in + np.arange(n)) * dt
    s_follow = start_m + speed_mps * t_follow
    r_out = ramp_out(float(s_follow[-1]), speed_mps, bounds)
    n_out = max(1, math.ceil(r_out.duration_s / dt))
    s_out, _, _ = r_out.at(np.arange(1, n_out + 1) * dt)
    sigma = np.concatenate([s_in, s_follow, s_out])
    held = np.concatenate([np.zeros(n_in, int), np.arange(n), np.full(n_out, n - 1)])
    return sigma, held, r_in, r_out
