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

import functools
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict, TypeVar

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.body import LYING_KINDS, Body, BodyKind
from cellrunner.model.expand import Step
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.geometry import Placed
from cellrunner.model.step import StepKind
from cellrunner.model.step_kinds import kind_of
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory
from cellrunner.planning.egress import corridors, egress_pose
from cellrunner.planning.world import CellWorld

_R = TypeVar("_R")

if TYPE_CHECKING:
    from cellrunner.model.cell import Gripper
    from cellrunner.planning.collision import CollisionModel, ContactAllowance
    from cellrunner.planning.kinematics import ArmKinematics
    from cellrunner.planning.timing import MotionLimits

#: standing still before a grip's wrist baseline, and before weighing after a lift (s);
#: the execution engine uses the same figures (execution.steps SETTLE_S + AVERAGE_S)
WRIST_SETTLE_S = 0.15
#: how far a carried part may press into the surface it is set down on or lifted off (m)
SET_DOWN_PRESS_M = 0.001
#: how far the tool may press into a waiting part it reaches around to grip (m)
GRIP_PRESS_M = 0.001
#: blends where a joint move meets a straight step (:func:`_blend`): at most this share
#: of the straight step's line and this distance (m) from the corner, like the radii a
#: UR integrator sets (bench/polyscope.py uses the same)
LINEAR_BLEND_FRACTION = 0.4
BLEND_RADIUS_MAX_M = 0.05
#: between two joint moves of different steps: this share of each adjacent edge
CORNER_FRACTION = 0.35
BLEND_POINTS = 24
#: m/s^2 (:meth:`TaskPlan.gravity_base_mps2`)
GRAVITY_MPS2 = 9.81
#: timed groups remembered per cell, least recently used out (:func:`_timed_pieces`). The
#: groups slots share (the pick, the retry path) are used by every slot and stay; in
#: ``serve`` every job that starts where a fault left the arm adds groups used once, and
#: with 256 kept (cleared when full) they grew its memory for hundreds of jobs (bench_plc)
TIMING_MEMO_SIZE = 64
#: planned motions remembered per cell (:meth:`StepPlanner.motion`), oldest out
MOTION_MEMO_SIZE = 256


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
        try:
            motion = planner.motion(StepPlan(step), goal_q=goal_q, allowances=allowances)
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
    ``on_step(step)`` is called as each step's planning starts (for a progress bar)."""
    from cellrunner.planning.placed import earlier_slot_parts

    # the parts earlier jobs left on the slots before this job's: there from the start
    world = world.with_placed(*earlier_slot_parts(world, steps))
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
                group.append(_at(step, planner.motion, row, then=then))
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
        for row in rows:
            if row.step.retry is not None:
                _check_retry_path(world, row, rows)
        from cellrunner.planning.jaw_hold import check_jaw_hold
        from cellrunner.planning.suction_hold import check_suction_hold

        check_suction_hold(world, rows)
        check_jaw_hold(world, rows)
    except InfeasibleError as exc:
        failed = next((r for r in rows if r.step.index == exc.step_index), current or rows[-1])
        failed.status, failed.message = "failed", exc.reason
        plan.failures.append(
            replace(exc.failure, step_index=failed.step.index, step=failed.step.label)
        )
        for r in rows:
            if r is not failed and (
                r.step.index > failed.step.index or (r.step.is_motion and r.approved is None)
            ):
                r.status, r.approved = "not planned", None
    return plan


def _at(step: Step, action: Callable[..., _R], *args: object, **kwargs: object) -> _R:
    """``action(*args, **kwargs)``, its InfeasibleError marked as about ``step``."""
    try:
        return action(*args, **kwargs)
    except InfeasibleError as exc:
        raise exc.at_step(step.index, step.label) from None


#: a force step's line accelerates and stops at most this hard at the TCP (m/s^2): the
#: tool's mass and the servo's response push on the wrist sensor by about 2 N per m/s^2
#: (the peg tool on the twin: 1.1 N at ur_rtde moveUntilContact's default 0.5 m/s^2, and
#: 2.2 N at the ~5 m/s^2 the joint limits allowed, which a 1.5 N probe took for a contact
#: in the air). At 0.1 the push stays near 0.2 N; the ramps cost v / a (0.1 s at 10 mm/s)
FORCE_TCP_ACCEL_MPS2 = 0.1
#: a place's descend sets its part down on its support: its line speeds up and brakes at
#: most this hard at the TCP (m/s^2), as a careful program sets a part down. Braking at
#: the joints' limits (~40 m/s^2 at a UR10e's TCP, from 1.5 m/s in 30 ms) onto a part
#: that ends on its table leaves no room for the arm's tracking (issue 33: the twin's
#: UR10e pressed the part into the table, 198 N). Costs ~0.3 s on an 80 mm descend
SET_DOWN_TCP_ACCEL_MPS2 = 2.0
#: what a joint move whose proven path fails verification by a hair is planned keeping
#: beyond the verifier's clearance (m), before the refusal stands (:func:`_plan_with_margin`)
PLAN_MARGIN_M = 0.5e-3


class StepPlanner:
    """Walks the steps, tracking the configuration and the carried part."""

    def __init__(self, world: CellWorld, q: np.ndarray, part: Placed | None) -> None:
        self.world, self.q, self.part = world, q, part
        self.allowances: tuple[ContactAllowance, ...] = ()
        #: where the first motion goes first, straight back, if it is a planned move
        #: (:mod:`.egress`): the job starts with the gripper down at a pick or place
        self.egress: tuple[np.ndarray, str] | None = None
        self.contact: tuple[
            ContactAllowance, ...
        ] = ()  # a force step's or tight fit's contacts, which the next straight move leaves

    def limits_for(
        self, step: Step, line_q: tuple[np.ndarray, np.ndarray] | None = None
    ) -> MotionLimits:
        """The limits ``step`` is timed and verified with; a force step's also depend on
        its line (``line_q``: the joint configurations at its ends)."""
        limits = self.world.limits
        if "tracked" in step.extra:  # on a moving belt: room left for the belt's motion
            from cellrunner.planning.belt_ramp import tracked_limits

            conveyor = self.world.loaded.cell.conveyors[step.extra["tracked"]]
            limits = tracked_limits(limits, float(conveyor.speed_max))
        speed = getattr(step.args, "speed", None)
        if step.is_planned:
            return limits.scaled(speed_fraction=speed if speed is not None else 1.0)
        if step.is_guarded or sets_down(step, self.world):
            assert line_q is not None  # a force step or set-down is timed along its line
            accel = FORCE_TCP_ACCEL_MPS2 if step.is_guarded else SET_DOWN_TCP_ACCEL_MPS2
            return limits.scaled(
                tcp_speed_mps=speed, accel_fraction=self._gentle(limits, line_q, accel)
            )
        return limits.scaled(tcp_speed_mps=speed)

    def _gentle(
        self, limits: MotionLimits, line_q: tuple[np.ndarray, np.ndarray], accel_mps2: float
    ) -> float:
        """The fraction of the joint accelerations at which a line reaches ``accel_mps2``
        at the TCP: along the line joint j turns by about dq_j per metre of TCP travel
        (the chord's), so A m/s^2 there takes A |dq_j| rad/s^2 of it."""
        q0, q1 = line_q
        kin = self.world.kinematics
        length_m = float(np.linalg.norm(kin.p_world_tcp(q1) - kin.p_world_tcp(q0)))
        if length_m <= 0.0:
            return 1.0
        need = np.abs(q1 - q0) / length_m * accel_mps2 / limits.joint_accel_rad_s2
        return min(1.0, float(need.max()))

    def collision(
        self, allowances: tuple[ContactAllowance, ...] = (), step: Step | None = None
    ) -> CollisionModel:
        """The cell's model with the carried part, ``allowances``, and the clearance
        ``step`` keeps (its own ``clearance:``, SPEC section 12)."""
        from cellrunner.planning.tight_fit import step_clearance_m

        model = self.world.collision.carrying(self.part)
        model = model.allowing(*allowances) if allowances else model
        clearance = step_clearance_m(step)
        return model.keeping(clearance) if clearance is not None else model

    def motion(
        self,
        row: StepPlan,
        goal_q: np.ndarray | None = None,
        allowances: tuple[ContactAllowance, ...] | None = None,
        then: Step | None = None,
    ) -> _Motion:
        """``row``'s step planned from where the planner stands (to ``goal_q`` when given,
        with ``allowances`` when given; ``then``: the step after it). A move planned
        before from the same state (configuration, tool, carried part, contacts) to the
        same goal is taken from the world's memo: the slots of a pattern share most of
        their moves."""
        key = self._motion_key(row.step, goal_q, allowances, then)
        memo = self.world.motion_memo
        hit: _Planned | None = memo.get(key)
        if hit is None:
            motion = self._plan_motion(row, goal_q, allowances, then)
            while len(memo) >= MOTION_MEMO_SIZE:
                memo.pop(next(iter(memo)))  # the oldest
            memo[key] = _Planned(motion, row.message, self.contact)
            return motion
        self.egress = None  # the first motion's alone
        self.contact = hit.contact_after
        m = hit.motion
        row.message, row.allowances, row.carrying = hit.message, m.row.allowances, self.part
        row.world, row.q_end_rad = self.world, m.waypoints[-1]
        self.q = m.waypoints[-1]
        return _Motion(
            row,
            m.waypoints,
            m.limits,
            m.line_m,
            m.collision,
            m.world,
            m.proven,
            m.then_proven,
            m.with_margin,
        )

    def _motion_key(
        self,
        step: Step,
        goal_q: np.ndarray | None,
        allowances: tuple[ContactAllowance, ...] | None,
        then: Step | None,
    ) -> tuple[object, ...]:
        """Everything :meth:`_plan_motion` reads: the step, the state, and the step after
        it when the move's IK looks ahead to a straight descend."""
        part = self.part
        follow = then if then is not None and then.kind in ("descend", "linear") else None
        return (
            step.index,
            step.kind,
            step.name,
            repr(step.args),
            _bytes(step.T_world_tcp),
            step.q_goal_deg,
            _bytes(goal_q),
            allowances,
            None if follow is None else (follow.kind, _bytes(follow.T_world_tcp)),
            np.asarray(self.q, float).tobytes(),
            id(self.world),
            None if part is None else (part.name, repr(part.shape), _bytes(part.T_parent_shape)),
            self.contact,
            None if self.egress is None else (_bytes(self.egress[0]), self.egress[1]),
        )

    def _plan_motion(
        self,
        row: StepPlan,
        goal_q: np.ndarray | None = None,
        allowances: tuple[ContactAllowance, ...] | None = None,
        then: Step | None = None,
    ) -> _Motion:
        from cellrunner.planning.cartesian import plan_linear

        step, kin = row.step, self.world.kinematics
        T_now = kin.T_world_tcp(self.q)
        proven: Callable[[], np.ndarray] | None = None  # a joint move's, planned proven
        then_proven: Callable[[], np.ndarray] | None = None
        with_margin: Callable[[], np.ndarray] | None = None
        egress, self.egress = self.egress, None  # the first motion's alone
        if step.is_planned:
            self.contact = ()  # a joint move leaves a force step's or tight fit's contacts behind
            if goal_q is None and step.q_goal_deg is not None:
                goal_q = np.radians(step.q_goal_deg)
            elif goal_q is None:
                assert step.T_world_tcp is not None  # a move has a joint or a frame target
                goal_q = self._ik(step.T_world_tcp, step, then)
            collision = self.collision()
            # sampled only: verification proves the timed trajectory, and a move that fails
            # it is planned again proven (_prove_sampled)
            head = self.q[None, :]
            if egress is not None:
                head = plan_linear(kin, collision, self.q, egress[0]).q_rad
                row.message = egress[1]
            path, loose = _sampled_joint_path(collision, head, goal_q)
            proven = functools.partial(_joint_path, collision, head, goal_q, proven=True)
            if loose is not None:
                proven, then_proven = loose, proven
            with_margin = functools.partial(_joint_path_with_margin, collision, head, goal_q)
            line = None
        else:
            from cellrunner.planning.tight_fit import named_contacts

            T_goal = self._linear_goal(step, T_now) if goal_q is None else kin.T_world_tcp(goal_q)
            if then is not None and then.kind == StepKind.GRIP:  # the jaws must fit the part first
                part = self.world.part_at(
                    then.extra.get("part_at", ""), T_goal, then.extra.get("part_pose")
                )
                check_jaws_fit(then, self.world.loaded.cell.tool.gripper, part)
            named = named_contacts(step)
            # also when replanned at run time from where the arm stands (a retry's retreat)
            touches = self._waiting_touches(T_goal)
            if allowances is None:
                if step.is_guarded:  # contact is what the step is for, where its line ends
                    from cellrunner.planning.force_plan import contact_allowances

                    allowances = self.contact + contact_allowances(self, step, T_goal) + named
                else:  # with self.contact
                    allowances = self._place_allowances(step, T_goal, named + touches)
            allowances = (*allowances, *(a for a in touches if a not in allowances))
            collision = self.collision(allowances, step)
            path = plan_linear(kin, collision, self.q, T_goal).q_rad
            kind_of(step.kind).check_line(self, step, path)
            # the next straight move leaves a force step's or tight fit's contacts
            self.contact = allowances if step.is_guarded or named else ()
            line = (T_now[:3, 3].copy(), T_goal[:3, 3].copy())
        row.allowances = tuple(allowances or ())
        row.carrying = self.part
        if step.is_guarded:
            from cellrunner.planning.force_plan import describe

            row.message = describe(step, line, row.allowances)
        limits = self.limits_for(step, (path[0], path[-1]))
        motion = _Motion(
            row, path, limits, line, collision, self.world, proven, then_proven, with_margin
        )
        row.world = self.world
        self.q = path[-1]
        row.q_end_rad = path[-1]
        return motion

    def act(self, row: StepPlan) -> None:
        """Plan a step that does not move (its kind's :meth:`plan`)."""
        kind_of(row.step.kind).plan(self, row)

    def _ik(self, T_world_tcp: np.ndarray, step: Step, then: Step | None) -> np.ndarray:
        """The branch nearest the current configuration that is collision-free and, when
        a straight descend follows, from which that descend runs clear to its goal on the
        same branch (else the nearest whose descend's goal is clear)."""
        from cellrunner.planning.blockers import every_branch_collides, unreachable

        kin = self.world.kinematics
        branches = kin.ik_all(T_world_tcp, self.q)
        collision = self.collision()
        if not branches:
            raise unreachable(
                step.label,
                kin,
                collision,
                T_world_tcp,
                self.q,
                getattr(step.args, "distance", None) if step.kind == StepKind.APPROACH else None,
            )
        follow = (
            then.T_world_tcp if then is not None and then.kind in ("descend", "linear") else None
        )
        valid = [q for q in branches if collision.is_valid(q)]
        if not valid:
            raise every_branch_collides(step.label, kin, collision, T_world_tcp, self.q)
        if follow is not None and then is not None:
            from cellrunner.planning.tight_fit import named_contacts

            named, touches = named_contacts(then), self._waiting_touches(follow)

            def line_model(q: np.ndarray, q_next: np.ndarray) -> CollisionModel:
                """The model the line after the approach is planned with from branch
                ``q``: what the part may touch where it sets down depends on the branch
                (the nearest branch's arm may pass the support closer than the part)."""
                allowances = self._place_allowances(then, follow, named, (q, q_next))
                return self.collision(allowances + touches, then)

            ends_clear = [
                (q, after)
                for q in valid
                if (q_next := kin.ik_track(follow, q)) is not None
                and (after := line_model(np.asarray(q), q_next)).is_valid(q_next)
            ]
            # the first branch whose whole line down is clear: another branch's descend
            # may pass an arm link by a fixture on its way (issue 33)
            for q, after in ends_clear:
                if _line_plans(kin, after, np.asarray(q), follow):
                    return np.asarray(q)
            if ends_clear:
                return np.asarray(ends_clear[0][0])  # its descend will say what is in the way
        return np.asarray(valid[0])  # the descend that follows will say what is wrong with it

    def _linear_goal(self, step: Step, T_now: np.ndarray) -> np.ndarray:
        return kind_of(step.kind).line_goal(self, step, T_now)

    def _place_allowances(
        self,
        step: Step,
        T_goal: np.ndarray,
        named: tuple[ContactAllowance, ...] = (),
        ends_q: tuple[np.ndarray, np.ndarray | None] | None = None,
    ) -> tuple[ContactAllowance, ...]:
        """The carried part may touch the fixture it rests on where a straight move starts
        (lifting it off) or ends (setting it down), and only that fixture; and the fixtures
        the step names in ``contact:`` (``named``) anywhere along it. ``ends_q``: the
        line's start and end configurations, where they are not where the planner stands
        and the nearest branch of ``T_goal`` (an approach weighing a branch for the line
        after it)."""
        from cellrunner.planning.collision import STALL_M, ContactAllowance
        from cellrunner.planning.placed import beside_refusal

        if self.part is None or not step.is_line:
            return self.contact + named
        q_start, q_goal = ends_q if ends_q is not None else (self.q, self._try_ik(T_goal))
        # a force step's contact comes first: the part leaves it as deep as the step let it
        # go (the set-down rule below is for the surfaces it is lifted off or set down on)
        allowances: list[ContactAllowance] = [*self.contact, *named]
        for end, q in (("start", q_start), ("end", q_goal)):
            if q is None:
                continue
            model = self.collision(tuple(allowances), step)
            for _ in range(3):
                clearance = model.clearance(q)
                if (
                    clearance.distance_m >= clearance.required_m + STALL_M
                    or clearance.a.kind is not BodyKind.PART
                    or clearance.a.name != self.part.name
                    or not clearance.b.is_obstacle
                ):
                    break
                # valid is clear by STALL_M more than required (the verifier's rule): within
                # that, a part set down rests on what is under it, and keeps clear of the rest
                # (a hole's walls stay walls unless the step names them in contact:)
                if clearance.distance_m >= clearance.required_m and not self._under(
                    clearance.b.fixture_name, q
                ):
                    break
                if not self._under(clearance.b.fixture_name, q) and (
                    beside := beside_refusal(step, self.part.name, clearance, end)
                ):
                    raise InfeasibleError(beside)
                if clearance.distance_m < -SET_DOWN_PRESS_M:
                    depth_mm = -clearance.distance_m * 1000
                    reason = (
                        f"at its {end} the part '{self.part.name}' would be {depth_mm:.1f} mm inside "
                        f"{clearance.b} (setting a part down may press {SET_DOWN_PRESS_M * 1000:.0f} mm at most)"
                    )
                    # about ``step``, which may be the descend an approach looks ahead to
                    raise InfeasibleError(
                        Failure(
                            FailureKind.SUPPORT,
                            reason,
                            blockers=(Blocker(clearance.b, clearance.distance_m),),
                            fix=f"move the target up by {depth_mm - SET_DOWN_PRESS_M * 1000:.1f} mm or more",
                            step_index=step.index,
                            step=step.label,
                        )
                    )
                support = clearance.b.fixture_name
                allowances.append(ContactAllowance(support, "part", -SET_DOWN_PRESS_M))
                # the jaws around a short part come down to what it is set on (or lifted off)
                allowances.append(ContactAllowance(support, "tool", -GRIP_PRESS_M))
                model = self.collision(tuple(allowances), step)
        return tuple(allowances)

    def _under(self, name: str, q: np.ndarray) -> bool:
        """Whether fixture (or waiting part) ``name`` is what the carried part rests on at
        ``q``: a thin probe from the part's centre straight down, to the clearance below
        its lowest point, meets it (as :func:`~.support.check_support` finds a support; a
        hole's wall beside the part is not under it)."""
        from cellrunner.planning.collision import STALL_M
        from cellrunner.planning.support import distances, down_probe

        assert self.part is not None  # a part is being set down
        T_world_part = self.world.kinematics.T_world_tcp(q) @ self.part.T_parent_shape
        below_m = self.world.collision.clearance_m + STALL_M
        probe = down_probe(self.part, T_world_part, below_m)
        things = [t for t in (*self.world.fixtures, *self.world.waiting_parts) if t.name == name]
        return any(d <= STALL_M for d in distances(self.world, probe, things))

    def _waiting_touches(self, T_goal: np.ndarray) -> tuple[ContactAllowance, ...]:
        """A straight move's tool may touch the parts waiting at their frames that it is
        within clearance of where the line starts or ends: the jaws or cups reaching to a
        part to grip it, or leaving it (a retry's retreat); never the joint moves, whose
        sweep must keep clear of every waiting part (SPEC section 12). Around a short part
        the jaws may also come down to the fixture it rests on (as far as onto the part)."""
        from cellrunner.planning.collision import ContactAllowance

        if not self.world.waiting_parts:
            return ()
        model = self.collision()
        names: set[str] = set()
        supports: set[str] = set()
        gripped: set[str] = set()  # the part a grip here takes: the tool may reach into it
        for q in (self.q, self._try_ik(T_goal)):
            violations = model.violations(q) if q is not None else []
            touched = {
                v.b.fixture_name
                for v in violations
                if v.a.kind is BodyKind.TOOL and v.b.kind in LYING_KINDS
            }
            names |= touched
            held = self._waiting_at_tcp(q) if q is not None else set()
            gripped |= held & touched
            under = {f for name in held for f in self.world.waiting_supports.get(name, ())}
            supports |= {
                v.b.name
                for v in violations
                if v.a.kind is BodyKind.TOOL and v.b.kind is BodyKind.FIXTURE and v.b.name in under
            }
        return tuple(
            ContactAllowance(name, "tool", -1.0 if name in gripped else -GRIP_PRESS_M)
            for name in sorted(names)
        ) + tuple(ContactAllowance(f, "tool", -GRIP_PRESS_M) for f in sorted(supports))

    def _waiting_at_tcp(self, q: np.ndarray) -> set[str]:
        """The waiting parts a grip at ``q`` would take: those whose bounding sphere holds
        the TCP (centred between jaws, or the top face under the cups)."""
        from cellrunner.planning.coal_shapes import make_coal_shape

        p = self.world.kinematics.p_world_tcp(q)
        return {
            part.name
            for part in self.world.waiting_parts
            if np.linalg.norm(np.asarray(part.T_parent_shape)[:3, 3] - p)
            <= make_coal_shape(part.shape)[1]
        }

    def frame_at_tcp(self) -> str:
        """The frame of the part a grip here takes (:meth:`_waiting_at_tcp`), or ''."""
        names = {Body.fixture(name).name for name in self._waiting_at_tcp(self.q)}
        return next((p.at for p in self.world.loaded.cell.parts if p.name in names), "")

    def _try_ik(self, T: np.ndarray) -> np.ndarray | None:
        try:
            return np.asarray(self.world.kinematics.ik_nearest(T, self.q))
        except InfeasibleError:
            return None


@dataclass(frozen=True)
class _Planned:
    """A motion as planned (:meth:`StepPlanner.motion`'s memo): its waypoints, limits,
    line, models, the row's message, and the contacts the planner keeps after it."""

    motion: _Motion
    message: str
    contact_after: tuple[ContactAllowance, ...]


def _line_plans(
    kin: ArmKinematics, collision: CollisionModel, q_start: np.ndarray, T_goal: np.ndarray
) -> bool:
    """True when a straight line from ``q_start`` to ``T_goal`` plans clear."""
    from cellrunner.planning.cartesian import plan_linear

    try:
        plan_linear(kin, collision, q_start, T_goal)
    except InfeasibleError:
        return False
    return True


def _bytes(a: np.ndarray | None) -> bytes | None:
    return None if a is None else np.asarray(a, float).tobytes()


def check_jaws_fit(step: Step, gripper: Gripper | None, part: Placed | None) -> None:
    """A parallel gripper's open jaws must be wider than the part across them (the TCP's
    X axis), or the grip cannot close around it: the twin's jaws land on it."""
    from cellrunner.model.gripper import width_across_jaws_m

    if part is None or gripper is None or gripper.kind == "vacuum":
        return
    width = width_across_jaws_m(part.shape, part.T_parent_shape)
    if width is None or width < gripper.stroke:
        return
    reason = (
        f"part '{part.name}' is {width * 1000:.1f} mm across the jaws (along the "
        f"TCP's X) but they open {gripper.stroke * 1000:.1f} mm (tool.gripper.stroke)"
    )
    fix = (
        "fix: a gripper with a longer stroke, or grip the part across a narrower side (turn "
        "the frame's rpy about its Z)"
    )
    # about the grip, also when the descend before it looks ahead to it
    raise InfeasibleError(
        Failure(
            FailureKind.GRIP,
            reason,
            blockers=(Blocker(Body(BodyKind.PART, part.name)),),
            fix=fix,
            step_index=step.index,
            step=step.label,
        )
    )


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


def _joins(before: Step, after: Step, world: CellWorld) -> bool:
    """Whether ``after`` may continue ``before`` without stopping: a joint move after any
    motion, a straight move only after a joint move (two straight lines meet at a corner)."""
    if after.is_guarded:  # a force step starts standing, for its wrist baseline
        return False
    if sets_down(after, world):  # timed gently from rest (StepPlanner.limits_for)
        return False
    return not after.is_line or not before.is_line


def sets_down(step: Step, world: CellWorld | None = None) -> bool:
    """Whether ``step`` comes down onto something, timed at ``SET_DOWN_TCP_ACCEL_MPS2``:
    a place's descend (the part onto its support), or a pick's with suction cups (the
    cups onto the part's face; jaws come down around a part, touching nothing)."""
    if step.kind != StepKind.DESCEND:
        return False
    macro = step.macro or ""
    if macro.startswith("place "):
        return True
    gripper = world.loaded.cell.tool.gripper if world is not None else None
    return macro.startswith("pick ") and gripper is not None and gripper.kind == "vacuum"


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


def _blend(world: CellWorld, group: list[_Motion]) -> list[_Motion]:
    """The group with each corner between two motions rounded by a quadratic Bezier arc in
    joint space, as a PolyScope blend radius does: it leaves the first motion at A and
    joins the second at B, with the corner as control point. On a straight step, A (or B)
    is at most ``LINEAR_BLEND_FRACTION`` of its line and ``BLEND_RADIUS_MAX_M`` from the
    corner, so the part end of a descend, lift or retreat stays straight; on a joint move,
    as far along its edge (joint-space distance) as the straight side, at most half of the
    edge. The arc belongs to the joint move and is checked with its collision model; the
    straight step keeps its (shorter) line, verified straight. Corners no arc clears stay
    sharp."""
    out = [
        _Motion(m.row, np.asarray(m.waypoints, float), m.limits, m.line_m, m.collision, m.world)
        for m in group
    ]
    kin = group[0].world.kinematics  # the tool mounted for this group
    for a, b in itertools.pairwise(out):
        a_line, b_line = a.line_m is not None, b.line_m is not None
        if (a_line and b_line) or _still(a.waypoints) or _still(b.waypoints):
            continue
        joint = b if a_line else a
        for shrink in (1.0, 0.5, 0.25):
            blended = _corner_arc(kin, a, b, shrink)
            if blended is not None and joint.collision.check_path(blended[2]).ok:
                a.waypoints, b.waypoints = blended[0], blended[1]
                if a.line_m is not None:
                    a.line_m = (a.line_m[0], kin.p_world_tcp(a.waypoints[-1]))
                if b.line_m is not None:
                    b.line_m = (kin.p_world_tcp(b.waypoints[0]), b.line_m[1])
                break
    return out


def _still(q_rad: np.ndarray) -> bool:
    return float(np.abs(q_rad - q_rad[0]).max()) < 1e-9


def _corner_arc(
    kin: ArmKinematics, a: _Motion, b: _Motion, shrink: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(a's waypoints, b's waypoints, the arc) with the corner between them rounded
    (:func:`_blend`); the arc is the start of the joint move (or its end when b is the
    straight one). None when a side is too short to blend."""
    corner = a.waypoints[-1]
    t = np.linspace(0.0, 1.0, BLEND_POINTS)[:, None]

    def straight_point(line_q: np.ndarray, from_end: bool) -> int | None:
        p = kin.p_world_tcp_many(line_q)
        length = float(np.linalg.norm(p[-1] - p[0]))
        radius = min(LINEAR_BLEND_FRACTION * length, BLEND_RADIUS_MAX_M) * shrink
        d = np.linalg.norm(p - (p[-1] if from_end else p[0]), axis=1)
        inside = np.nonzero(d < radius)[0]
        if radius <= 1e-4 or len(inside) == 0:
            return None
        k = inside[0] if from_end else inside[-1]  # the farthest sample within the radius
        return int(k) if 0 < k < len(line_q) - 1 else None

    def rounded(start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """The quadratic Bezier arc from ``start`` through the corner's pull to ``end``."""
        return np.asarray((1 - t) ** 2 * start + 2 * (1 - t) * t * corner + t**2 * end)

    def along(edge_from: np.ndarray, edge_to: np.ndarray, distance: float) -> np.ndarray:
        edge = edge_to - edge_from
        length = float(np.linalg.norm(edge))
        return np.asarray(edge_from + edge * min(distance / max(length, 1e-12), 0.5))

    if a.line_m is not None:  # straight -> joint
        if len(b.waypoints) < 2:
            return None
        k = straight_point(a.waypoints, from_end=True)
        if k is None:
            return None
        start = a.waypoints[k]
        end = along(corner, b.waypoints[1], float(np.linalg.norm(corner - start)))
        arc = rounded(start, end)
        return a.waypoints[: k + 1], np.vstack([arc, b.waypoints[1:]]), arc
    if b.line_m is not None:  # joint -> straight
        if len(a.waypoints) < 2:
            return None
        k = straight_point(b.waypoints, from_end=False)
        if k is None:
            return None
        end = b.waypoints[k]
        start = along(corner, a.waypoints[-2], float(np.linalg.norm(end - corner)))
        arc = rounded(start, end)
        return np.vstack([a.waypoints[:-1], arc]), b.waypoints[k:], arc
    if len(a.waypoints) < 2 or len(b.waypoints) < 2:  # joint -> joint
        return None
    f = CORNER_FRACTION * shrink
    start = along(corner, a.waypoints[-2], f * float(np.linalg.norm(a.waypoints[-2] - corner)))
    end = along(corner, b.waypoints[1], f * float(np.linalg.norm(b.waypoints[1] - corner)))
    arc = rounded(start, end)
    return np.vstack([a.waypoints[:-1], arc]), np.vstack([arc[-1:], b.waypoints[1:]]), arc


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
