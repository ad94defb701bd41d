"""Planning a whole task: every expanded step, from a start configuration, to a
:class:`TaskPlan` whose motion steps each carry a verified, sealed trajectory.

Rules (SPEC section 10):
- ``move``/``approach``: IK nearest the current configuration, then a collision-free
  joint path (direct, else RRTConnect); ``descend``/``linear``/``lift``/``retreat``: a
  straight TCP line within 1 mm;
- consecutive motions with no reason to stop are timed as one non-stop trajectory (e.g.
  approach -> descend, retreat -> move), cut back into one piece per step, their corners
  blended (:func:`_blend`: a collision-checked arc, the part end of a straight step kept
  straight); two straight steps never join, a lift after a grip with a force window ends
  at rest (the part is weighed), and grip, release, IO and waits stand still;
- the carried part joins the collision model from its grip to its release; when a place
  sets the part down, the fixture it lands on may be touched (ContactAllowance);
- every piece passes :func:`verify_trajectory` (limits x margin, TCP cap, continuity,
  straightness, collisions) before it is sealed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.expand import Step
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.geometry import Placed
from cellrunner.model.step import StepKind
from cellrunner.model.trajectory import ApprovedTrajectory
from cellrunner.planning.corner_blend import LINEAR_BLEND_FRACTION
from cellrunner.planning.egress import corridors, egress_pose
from cellrunner.planning.group_timing import (
    TIMING_MEMO_SIZE,
    _same_limits,
    _time_and_verify,
    _time_group,
    seal,
)
from cellrunner.planning.step_plan import StepPlan, VerifyInputs, _Motion
from cellrunner.planning.step_planner import (
    FORCE_TCP_ACCEL_MPS2,
    SET_DOWN_TCP_ACCEL_MPS2,
    WRIST_SETTLE_S,
    StepPlanner,
    check_jaws_fit,
    sets_down,
)
from cellrunner.planning.world import CellWorld

# the names other modules import from here; they live in the modules named above
__all__ = [
    "FORCE_TCP_ACCEL_MPS2",
    "GRAVITY_MPS2",
    "LINEAR_BLEND_FRACTION",
    "SET_DOWN_TCP_ACCEL_MPS2",
    "TIMING_MEMO_SIZE",
    "WRIST_SETTLE_S",
    "StepPlan",
    "StepPlanner",
    "TaskPlan",
    "VerifyInputs",
    "check_jaws_fit",
    "plan_task",
    "seal",
    "sets_down",
]

_R = TypeVar("_R")

if TYPE_CHECKING:
    from cellrunner.planning.collision import ContactAllowance


#: m/s^2 (:meth:`TaskPlan.gravity_base_mps2`)
GRAVITY_MPS2 = 9.81


@dataclass
class TaskPlan:
    """The approved plan of one job; implements the engine's ``Motions``."""

    world: CellWorld
    steps: list[Step]
    rows: list[StepPlan]
    q_start_rad: np.ndarray
    #: why the plan is refused, as data (an on_error step's index follows the job's)
    failures: list[Failure] = field(default_factory=list)
    on_error: list[StepPlan] = field(default_factory=list)  # verified from the plan's states
    warnings: list[Failure] = field(default_factory=list)  # on_error steps skipped from some states

    @property
    def ok(self) -> bool:
        return not self.failures

    @property
    def errors(self) -> list[str]:
        """Each failure as one line naming its step (``on_error`` in front of the task's
        on_error steps)."""
        return [f.text() for f in self.failures]

    @property
    def cycle_time_s(self) -> float:
        return float(sum(r.duration_s for r in self.rows))

    def row(self, step: Step) -> StepPlan | None:
        return next((r for r in self.rows if r.step.index == step.index and r.step is step), None)

    # -- Motions (the engine's view) --------------------------------------------------------
    def nominal(self, step: Step) -> ApprovedTrajectory | None:
        """The approved trajectory of ``step``; a plan read from the cache is verified
        here, on first use, before anything can stream it."""
        row = self.row(step)
        if row is None:
            return None
        if row.approved is None and row.trajectory is not None:
            row.approved = seal(self.world, row)
        return row.approved

    def continues(self, step: Step) -> bool:
        row = self.row(step)
        return bool(row is not None and row.verify_inputs and row.verify_inputs["previous_moving"])

    def replan(
        self,
        step: Step,
        q_now_rad: np.ndarray,
        carrying: bool,
        obstacles: Placed | None = None,
    ) -> ApprovedTrajectory:
        """A verified rest-to-rest trajectory from ``q_now_rad`` to the step's goal: the
        same goal as planned (after a stop), or, for a relative move planned nowhere (a
        retry's retreat), its distance from where the arm stands. ``obstacles`` (the
        watched zone's map) are planned around and verified against like fixtures."""
        row = self.row(step)
        if row is None and "corrects" in step.extra:  # a step an align moved: as planned, elsewhere
            row = self.row(step.extra["corrects"])
        part = (
            row.carrying if row is not None else (self._carried_before(step) if carrying else None)
        )
        allowances = row.allowances if row is not None else ()
        world = self._world_of(step)
        if obstacles is not None:
            world = world.with_obstacles(obstacles)
        planner = StepPlanner(world, np.asarray(q_now_rad, float), part)
        goal_q = (
            row.q_end_rad if row is not None and row.status == "ok" and row.step is step else None
        )
        then = self._line_after(step) if obstacles is not None else None
        # a joint move an align corrected: its branch is chosen with the corrected line
        # after it, as check chose it for the corrections it proved (one judgement)
        ahead = self._corrected_line_after(step) if goal_q is None else None
        try:
            motion = planner.motion(
                StepPlan(step), goal_q=goal_q, allowances=allowances, then=ahead
            )
            if then is not None:
                self._line_clear(world, then, motion.waypoints[-1])
        except InfeasibleError:
            if obstacles is None or goal_q is None or step.T_world_tcp is None:
                raise
            # the planned arm configuration at the goal, or the straight line that follows
            # from it, meets the map: the same goal pose in another configuration whose
            # line is clear (the steps after it then start from where it ends)
            motion = self._other_branch(world, step, q_now_rad, part, allowances, then)
        approved = _time_and_verify(world, motion, np.asarray(q_now_rad, float)).approved
        assert approved is not None  # _time_and_verify approves every row or raises
        return approved

    def _line_after(self, step: Step) -> Step | None:
        """The straight line that follows the joint move ``step`` (a descend), if one does."""
        if not step.is_planned:
            return None
        after = [s for s in self.steps if s.index == step.index + 1]
        return after[0] if after and after[0].kind in ("descend", "linear") else None

    def _corrected_line_after(self, step: Step) -> Step | None:
        """The straight line after the joint move ``step`` that an align corrected (a
        pick's approach), moved by the same correction: None for any other step."""
        original = step.extra.get("corrects")
        if original is None or original.T_world_tcp is None or step.T_world_tcp is None:
            return None
        line = self._line_after(original)
        if line is None or line.T_world_tcp is None:
            return None
        if line.extra.get("aligned_frame") != step.extra.get("aligned_frame"):
            return line
        # the correction in world axes: T_corrected = W @ T_planned
        W = step.T_world_tcp @ np.linalg.inv(original.T_world_tcp)
        return replace(
            line, T_world_tcp=W @ line.T_world_tcp, extra={**line.extra, "corrects": line}
        )

    def _line_clear(self, world: CellWorld, line: Step, q_rad: np.ndarray) -> None:
        """Raise InfeasibleError unless ``line`` plans from ``q_rad`` in ``world``."""
        row = self.row(line)
        part = row.carrying if row is not None else self._carried_before(line)
        allowances = row.allowances if row is not None else None
        StepPlanner(world, q_rad, part).motion(StepPlan(line), allowances=allowances)

    def _other_branch(
        self,
        world: CellWorld,
        step: Step,
        q_now_rad: np.ndarray,
        part: Placed | None,
        allowances: tuple[ContactAllowance, ...],
        then: Step | None,
    ) -> _Motion:
        """``step`` planned to the first other IK branch of its goal pose (nearest first)
        that is clear in ``world`` and from which the line ``then`` is clear too."""
        assert step.T_world_tcp is not None
        q_now = np.asarray(q_now_rad, float)
        collision = StepPlanner(world, q_now, part).collision()
        why: InfeasibleError | None = None
        for q_goal in world.kinematics.ik_all(step.T_world_tcp, q_now):
            if not collision.is_valid(q_goal):
                continue
            try:
                planner = StepPlanner(world, q_now, part)
                motion = planner.motion(StepPlan(step), goal_q=q_goal, allowances=allowances)
                if then is not None:
                    self._line_clear(world, then, q_goal)
                return motion
            except InfeasibleError as exc:
                why = why or exc
        raise why or InfeasibleError(
            Failure(
                FailureKind.COLLISION,
                "every arm configuration at it meets the map",
                step_index=step.index,
                step=step.label,
            )
        )

    def _world_of(self, step: Step) -> CellWorld:
        worlds = [r.world for r in self.rows if r.step.index <= step.index and r.world is not None]
        return worlds[-1] if worlds else self.world

    def tcp_position_m(self, q_rad: np.ndarray, step: Step | None = None) -> np.ndarray:
        """World TCP position at ``q_rad``, with the tool mounted at ``step`` (default: at start)."""
        world = self.world if step is None else self._world_of(step)
        return np.asarray(world.kinematics.p_world_tcp(q_rad))

    def tcp_positions_m(self, q_rad: np.ndarray) -> np.ndarray:
        """World TCP positions (N x 3) at the rows of ``q_rad``, tool mounted at start."""
        return self.world.kinematics.p_world_tcp_many(q_rad)

    def tcp_pose(self, q_rad: np.ndarray) -> np.ndarray:
        """T_world_tcp (4x4) at ``q_rad``, tool mounted at start."""
        return np.asarray(self.world.kinematics.T_world_tcp(q_rad))

    def tcp_lever_arms_m(self) -> np.ndarray:
        """Per joint, a bound on the TCP's distance from its axis (m), tool mounted at
        start (:attr:`ArmKinematics.tcp_lever_arms_m`)."""
        return self.world.kinematics.tcp_lever_arms_m

    def tcp_accel_base_mps2(self, q_rad: np.ndarray, rate_hz: float) -> np.ndarray:
        """The TCP's acceleration (N x 3, m/s^2, the robot base's axes, as the wrist
        wrench is read) along set-points ``q_rad`` streamed at ``rate_hz``: second
        differences, each end taking its neighbour's (tool mounted at start)."""
        q = np.asarray(q_rad, float)
        if len(q) < 3:
            return np.zeros((len(q), 3))
        p = self.world.kinematics.p_world_tcp_many(q)
        a = np.diff(p, 2, axis=0) * rate_hz * rate_hz
        R_world_base = self.world.kinematics.T_world_base[:3, :3]
        return np.asarray(np.vstack([a[:1], a, a[-1:]]) @ R_world_base)

    def gravity_base_mps2(self) -> np.ndarray:
        """Gravity (m/s^2) in the robot base's axes."""
        return np.asarray(
            np.array([0.0, 0.0, -GRAVITY_MPS2]) @ self.world.kinematics.T_world_base[:3, :3]
        )

    def carried_during(self, step: Step) -> Placed | None:
        """The part held while ``step`` runs (placed in the TCP frame), None when none."""
        return self._carried_before(step)

    def _carried_before(self, step: Step) -> Placed | None:
        rows = [r for r in self.rows if r.step.index <= step.index]
        return rows[-1].carrying if rows else None


#: how many other IK branches of a joint move's goal a job is planned again with when a
#: straight line after it fails on an arm link (:func:`_another_branch`)
BRANCH_REPLANS = 3


def plan_task(
    world: CellWorld,
    steps: list[Step],
    q_start_rad: np.ndarray,
    *,
    joined: bool = True,
    on_step: Callable[[Step], None] | None = None,
) -> TaskPlan:
    """Plan every step of a job; failures are recorded per step (the rest is not planned).
    ``joined=False`` (run --step) ends every motion at rest: the same waypoints, each
    timed from rest to rest, so that the job can pause between any two steps.
    ``on_step(step)`` is called as each step's planning starts (for a progress bar).

    A joint move's branch is chosen with the straight line right after it
    (:meth:`StepPlanner._ik`); when a later line of the same chain (the insert, the
    retreat after a release) meets an arm link or a singularity, the job is planned again
    with the move's other branches, nearest first (a ceiling-mounted UR10's retreat from a
    hole met the ceiling plate on the nearest branch, 0.07 mm short, where the branch the
    generator's witness stands on keeps 5 mm more: s5304). The first plan's refusal stands
    when none of them clears."""
    plan = _plan_once(world, steps, q_start_rad, joined, on_step, {})
    tried: list[np.ndarray] = []
    for _ in range(BRANCH_REPLANS):
        hint = _another_branch(world, plan, tried)
        if hint is None:
            break
        again = _plan_once(world, steps, q_start_rad, joined, on_step, dict([hint]))
        if again.ok:
            return again
    return plan


def _another_branch(
    world: CellWorld, plan: TaskPlan, tried: list[np.ndarray]
) -> tuple[int, np.ndarray] | None:
    """The joint move to plan again and the next untried branch of its goal, when
    ``plan`` failed on a straight line after it (nothing but straight lines and steps that
    do not move between them) where an arm link meets something or a singularity is near:
    another branch puts the arm elsewhere along the same TCP lines. None otherwise."""
    from cellrunner.model.body import BodyKind

    if not plan.failures:
        return None
    failure = plan.failures[0]
    arm = any(b.body.kind is BodyKind.ROBOT_LINK for b in failure.blockers)
    if not (
        failure.kind is FailureKind.SINGULARITY or (failure.kind is FailureKind.COLLISION and arm)
    ):
        return None
    rows = plan.rows
    at = next((i for i, r in enumerate(rows) if r.step.index == failure.step_index), None)
    if at is None or not rows[at].step.is_line:
        return None
    j = next((i for i in range(at - 1, -1, -1) if rows[i].step.is_planned), None)
    if j is None:
        return None
    move = rows[j]
    T_goal, q_used = move.step.T_world_tcp, move.q_end_rad
    if T_goal is None or move.step.q_goal_deg is not None or q_used is None:
        return None
    q_before = next(
        (r.q_end_rad for r in reversed(rows[:j]) if r.q_end_rad is not None), plan.q_start_rad
    )
    if not any(np.allclose(q_used, q, atol=1e-3) for q in tried):
        tried.append(np.asarray(q_used, float))
    for q in (move.world or world).kinematics.ik_all(T_goal, q_before):
        if not any(np.allclose(q, seen, atol=1e-3) for seen in tried):
            tried.append(np.asarray(q, float))
            return move.step.index, np.asarray(q, float)
    return None


def _plan_once(
    world: CellWorld,
    steps: list[Step],
    q_start_rad: np.ndarray,
    joined: bool,
    on_step: Callable[[Step], None] | None,
    goals: dict[int, np.ndarray],
) -> TaskPlan:
    """:func:`plan_task` once, the joint moves of ``goals`` (step index -> joint goal)
    planned to those goals."""
    from cellrunner.planning.placed import earlier_slot_parts, found_parts

    # the parts earlier jobs left on the slots before this job's, and those an align
    # finds off their frames: there from the start
    world = world.with_placed(*found_parts(world, steps), *earlier_slot_parts(world, steps))
    planner = StepPlanner(world, np.asarray(q_start_rad, float), None)
    planner.egress = egress_pose(
        corridors(steps, world.loaded.cell), world.kinematics.T_world_tcp(planner.q)
    )
    rows = [StepPlan(s, status="not planned") for s in steps]
    plan = TaskPlan(world, steps, rows, np.asarray(q_start_rad, float))
    group: list[_Motion] = []
    q_group_start = planner.q

    def flush() -> None:
        nonlocal group, q_group_start
        if group:
            _time_group(world, group, q_group_start, joined)
            group = []
        q_group_start = planner.q

    current: StepPlan | None = None
    try:
        for i, row in enumerate(rows):
            current = row
            step = row.step
            if on_step is not None:
                on_step(step)
            then = rows[i + 1].step if i + 1 < len(rows) else None
            if step.is_motion:
                if group and (
                    not _joins(group[-1].row.step, step, planner.world)
                    or not _same_limits(group[-1].limits, planner.limits_for(step))
                ):
                    flush()
                group.append(
                    _at(step, planner.motion, row, goal_q=goals.get(step.index), then=then)
                )
                if (
                    step.kind in (StepKind.DESCEND, StepKind.LINEAR)
                    or step.is_guarded
                    or _weighed(rows, i)
                ):
                    flush()  # ends at rest: something happens at its end (a grip, weighing the part, a contact)
            else:
                flush()
                _at(step, planner.act, row)
            row.status = "ok"
            row.world = row.world or planner.world
            if not step.is_motion:
                row.carrying = planner.part
        current = None
        flush()
        _check_whole_job(world, rows)
    except InfeasibleError as exc:
        _mark_failed(plan, exc, current)
    return plan


def _check_whole_job(world: CellWorld, rows: list[StepPlan]) -> None:
    """What needs the whole job planned: retry paths, and the grip holding the part
    through every move that carries it (cups, jaws)."""
    from cellrunner.planning.jaw_hold import check_jaw_hold
    from cellrunner.planning.suction_hold import check_suction_hold

    for row in rows:
        if row.step.retry is not None:
            _check_retry_path(world, row, rows)
    check_suction_hold(world, rows)
    check_jaw_hold(world, rows)


def _mark_failed(plan: TaskPlan, exc: InfeasibleError, current: StepPlan | None) -> None:
    """The row ``exc`` is about failed (``current`` where it names none); the rows after
    it, and the motions not yet approved, not planned."""
    rows = plan.rows
    failed = next((r for r in rows if r.step.index == exc.step_index), current or rows[-1])
    failed.status, failed.message = "failed", exc.reason
    plan.failures.append(replace(exc.failure, step_index=failed.step.index, step=failed.step.label))
    for r in rows:
        if r is not failed and (
            r.step.index > failed.step.index or (r.step.is_motion and r.approved is None)
        ):
            r.status, r.approved = "not planned", None


def _at(step: Step, action: Callable[..., _R], *args: object, **kwargs: object) -> _R:
    """``action(*args, **kwargs)``, its InfeasibleError marked as about ``step``."""
    try:
        return action(*args, **kwargs)
    except InfeasibleError as exc:
        raise exc.at_step(step.index, step.label) from None


def _joins(before: Step, after: Step, world: CellWorld) -> bool:
    """Whether ``after`` may continue ``before`` without stopping: a joint move after any
    motion, a straight move only after a joint move (two straight lines meet at a corner)."""
    if after.is_guarded:  # a force step starts standing, for its wrist baseline
        return False
    if sets_down(after, world):  # timed gently from rest (StepPlanner.limits_for)
        return False
    return not after.is_line or not before.is_line


def _weighed(rows: list[StepPlan], i: int) -> bool:
    """A lift right after a grip with a force window: the engine weighs the part at rest
    after it (execution.job), so the lift ends at rest."""
    step = rows[i].step
    return (
        step.kind == StepKind.LIFT
        and i > 0
        and rows[i - 1].step.kind == StepKind.GRIP
        and getattr(rows[i - 1].step.args, "force", None) is not None
    )


def _check_retry_path(world: CellWorld, row: StepPlan, rows: list[StepPlan]) -> None:
    """A grip's retry (its in-between steps, then the descend again) must be feasible too."""
    retry = row.step.retry
    assert retry is not None  # called for the rows of grips with a retry
    descend = next(r for r in rows if r.step.index == retry.redo_from)
    q_grip = descend.q_end_rad
    assert q_grip is not None  # the descend was planned before its grip
    world = descend.world or world
    planner = StepPlanner(world, q_grip, None)
    try:
        for between in [*retry.between, descend.step]:
            if between.is_motion:
                q_from = planner.q
                goal = q_grip if between is descend.step else None
                motion = _at(between, planner.motion, StepPlan(between), goal_q=goal)
                _time_and_verify(world, motion, q_from)
    except InfeasibleError as exc:
        failure = exc.failure
        raise InfeasibleError(
            replace(
                failure,
                reason=f"retry path: {failure.reason}",
                step_index=row.step.index,
                step=row.step.label,
            )
        ) from None
