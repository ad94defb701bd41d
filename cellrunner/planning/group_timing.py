"""Timing motions: a group of consecutive motions as one non-stop trajectory (TOPP-RA),
cut back into one verified piece per step (:func:`_time_group`), or one motion from rest
to rest; the verified pieces remembered per cell; a stored row verified again
(:func:`seal`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory
from cellrunner.planning.corner_blend import _blend
from cellrunner.planning.move_plans import _prove_sampled
from cellrunner.planning.step_plan import StepPlan, VerifyInputs, _Motion, _TimedPiece
from cellrunner.planning.step_planner import StepPlanner
from cellrunner.planning.world import CellWorld

if TYPE_CHECKING:
    from cellrunner.planning.timing import MotionLimits


#: timed groups remembered per cell, least recently used out (:func:`_timed_pieces`). The
#: groups slots share (the pick, the retry path) are used by every slot and stay; in
#: ``serve`` every job that starts where a fault left the arm adds groups used once, and
#: with 256 kept (cleared when full) they grew its memory for hundreds of jobs (bench_plc)
TIMING_MEMO_SIZE = 64


def _time_group(
    world: CellWorld, group: list[_Motion], q_start: np.ndarray, joined: bool = True
) -> None:
    """Time a group of motions as one non-stop trajectory with its corners blended
    (:func:`_blend`); if that fails verification, or not ``joined``, one by one from rest.
    Each time verification fails on a joint move the planner only sampled, that move is
    planned again proven (:func:`_prove_sampled`) and the group timed again."""
    if len(group) > 1 and joined:
        while True:
            try:
                _apply(world, group, _timed_pieces(world, _blend(world, group), q_start))
                return
            except InfeasibleError as exc:
                failed = next((m for m in group if m.row.step.index == exc.step_index), None)
                if failed is None or not _prove_sampled(failed):
                    break
    q = q_start
    for motion in group:
        piece = _verified_alone(world, motion, q)
        _apply(world, [motion], [piece])
        q = piece["trajectory"].q_rad[-1]


def _verified_alone(world: CellWorld, motion: _Motion, q_start: np.ndarray) -> _TimedPiece:
    """``motion`` timed from rest to rest and verified; planned again (proven, then
    keeping a margin) and timed again each time it fails verification."""
    while True:  # each failure takes the move's next plan: proven, then with a margin
        try:
            return _timed_pieces(world, [motion], q_start)[0]
        except InfeasibleError:
            if not _prove_sampled(motion):
                raise


def _time_and_verify(world: CellWorld, motion: _Motion, q_start: np.ndarray) -> StepPlan:
    """Time ``motion`` from rest to rest and apply the verified piece to its row."""
    _apply(world, [motion], [_verified_alone(world, motion, q_start)])
    return motion.row


def _apply(world: CellWorld, group: list[_Motion], pieces: list[_TimedPiece]) -> None:
    for motion, piece in zip(group, pieces, strict=True):
        row = motion.row
        row.approved, row.trajectory, row.verify_inputs = (
            piece["approved"],
            piece["trajectory"],
            piece["inputs"],
        )
        # every piece starts on the set-point before it (the start state, or the last
        # sample of the piece it continues), which the engine does not stream twice
        q = piece["trajectory"].q_rad
        row.duration_s = (len(q) - 1) / world.spec.rate_hz
        row.q_end_rad = q[-1]


def _timed_pieces(world: CellWorld, group: list[_Motion], q_start: np.ndarray) -> list[_TimedPiece]:
    """:func:`_time_pieces`, remembered per cell for the same inputs (the pattern slots of
    a job share their first motions, and a grip's retry path is the same for all): the
    same waypoints, limits, lines, collision models, step and start give the same
    verified pieces, since timing and verification are deterministic."""
    key = (
        np.asarray(q_start, float).tobytes(),
        tuple(
            (
                m.row.step.index,
                m.row.step.name,
                np.asarray(m.waypoints, float).tobytes(),
                id(m.collision),
                None if m.line_m is None else np.asarray(m.line_m, float).tobytes(),
                m.limits.joint_speed_rad_s.tobytes(),
                m.limits.joint_accel_rad_s2.tobytes(),
                m.limits.tcp_speed_mps,
            )
            for m in group
        ),
    )
    memo = world.timing_memo
    hit = memo.get(key)
    if hit is not None and all(a is m.collision for a, m in zip(hit[0], group, strict=True)):
        memo[key] = memo.pop(key)  # the most recently used goes last
        pieces: list[_TimedPiece] = hit[1]
        return pieces
    pieces = _time_pieces(world, group, q_start)
    memo.pop(key, None)
    while len(memo) >= TIMING_MEMO_SIZE:
        memo.pop(next(iter(memo)))  # the least recently used
    memo[key] = ([m.collision for m in group], pieces)
    return pieces


def _time_pieces(world: CellWorld, group: list[_Motion], q_start: np.ndarray) -> list[_TimedPiece]:
    """TOPP-RA over the group's joined waypoints, cut into one verified piece per motion
    (sharing boundary samples); raises InfeasibleError when a piece fails verification."""
    from cellrunner.planning.timing import time_path
    from cellrunner.planning.verify import verify_trajectory

    world = group[0].world  # the tool mounted for this group (a tool change flushes groups)
    waypoints = np.vstack([group[0].waypoints, *[m.waypoints[1:] for m in group[1:]]])
    s_waypoints = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1))]
    )
    timed = time_path(world.kinematics, waypoints, group[0].limits, world.spec.rate_hz)
    cuts = _cut_indices(timed.s, group, s_waypoints)
    previous = np.asarray(q_start, float)
    start = 0
    pieces: list[_TimedPiece] = []
    for i, (motion, end) in enumerate(zip(group, cuts, strict=True)):
        q = timed.q_rad[start : end + 1]
        if i == 0:
            q = np.vstack([previous[None, :], q[1:]]) if len(q) > 1 else previous[None, :]
        trajectory = Trajectory(world.spec.rate_hz, np.arange(len(q)) / world.spec.rate_hz, q)
        inputs = VerifyInputs(
            previous_q_rad=previous,
            # the arm runs into this piece from the one before only when that one moved:
            # a zero-length first piece (a move to where the arm stands) leaves it at rest
            previous_moving=i > 0 and start > 0,
            ends_at_rest=i == len(group) - 1,
            line_m=motion.line_m,
        )
        approved = verify_trajectory(
            trajectory,
            step_index=motion.row.step.index,
            step_name=motion.row.step.name,
            kinematics=world.kinematics,
            limits=motion.limits,
            collision=motion.collision,
            **inputs,
        )
        pieces.append({"trajectory": trajectory, "approved": approved, "inputs": inputs})
        # of the trajectory's own copy: a view of ``timed`` would keep the whole group alive
        previous = trajectory.q_rad[-2:]
        start = end  # the next piece shares this boundary sample
    return pieces


def seal(world: CellWorld, row: StepPlan) -> ApprovedTrajectory:
    """Verify a stored row's trajectory again with the inputs it was planned with."""
    from cellrunner.planning.verify import verify_trajectory

    world = row.world or world
    assert row.trajectory is not None and row.verify_inputs is not None  # a stored motion row
    planner = StepPlanner(world, row.trajectory.q_rad[0], row.carrying)
    return verify_trajectory(
        row.trajectory,
        step_index=row.step.index,
        step_name=row.step.name,
        kinematics=world.kinematics,
        limits=planner.limits_for(row.step, (row.trajectory.q_rad[0], row.trajectory.q_rad[-1])),
        collision=planner.collision(row.allowances, row.step),
        **row.verify_inputs,
    )


def _same_limits(a: MotionLimits, b: MotionLimits) -> bool:
    return (
        np.array_equal(a.joint_speed_rad_s, b.joint_speed_rad_s)
        and np.array_equal(a.joint_accel_rad_s2, b.joint_accel_rad_s2)
        and a.tcp_speed_mps == b.tcp_speed_mps
    )


def _cut_indices(s_samples: np.ndarray, group: list[_Motion], s_waypoints: np.ndarray) -> list[int]:
    """The last sample index of each motion in a joined trajectory (the next motion's
    first sample: joined pieces share their boundary sample). A straight motion keeps only
    samples on its own stretch of the path: it ends on the last sample at or before its
    end, and starts on the first sample at or after its start."""
    cuts: list[int] = []
    last = len(s_samples) - 1
    bound = -1
    for i, motion in enumerate(group[:-1]):
        bound += len(motion.waypoints) - (0 if i == 0 else 1)
        s_b = s_waypoints[bound]
        if motion.line_m is not None:
            k = int(np.searchsorted(s_samples, s_b + 1e-12, side="right")) - 1
        elif group[i + 1].line_m is not None:
            k = int(np.searchsorted(s_samples, s_b - 1e-12, side="left"))
        else:
            k = int(np.argmin(np.abs(s_samples - s_b)))
        cuts.append(min(max(k, cuts[-1] + 1 if cuts else 0), last))
    cuts.append(last)
    return cuts
