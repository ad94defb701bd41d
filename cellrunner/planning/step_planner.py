"""The step planner: walks a job's steps from a start configuration, planning each motion
to joint waypoints (``move``/``approach``: IK nearest the current configuration, then a
collision-free joint path; straight steps: a TCP line within 1 mm) with the limits it is
timed with, and each standing step through its kind's ``plan`` (SPEC section 10)."""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.body import Body, BodyKind
from cellrunner.model.expand import Step
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.geometry import Placed
from cellrunner.model.step import StepKind
from cellrunner.model.step_kinds import kind_of
from cellrunner.planning.move_plans import _joint_path, _joint_path_with_margin, _sampled_joint_path
from cellrunner.planning.step_contacts import StepContacts
from cellrunner.planning.step_plan import StepPlan, _Motion
from cellrunner.planning.world import CellWorld

if TYPE_CHECKING:
    from cellrunner.model.cell import Gripper
    from cellrunner.planning.collision import CollisionModel, ContactAllowance
    from cellrunner.planning.kinematics import ArmKinematics
    from cellrunner.planning.timing import MotionLimits


#: standing still before a grip's wrist baseline, and before weighing after a lift (s);
#: the execution engine uses the same figures (execution.steps SETTLE_S + AVERAGE_S)
WRIST_SETTLE_S = 0.15
#: planned motions remembered per cell (:meth:`StepPlanner.motion`), oldest out
MOTION_MEMO_SIZE = 256
#: how many of a goal's IK branches a joint move tries to reach before it is refused
MAX_GOAL_BRANCHES = 4
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


class StepPlanner(StepContacts):
    """Walks the steps, tracking the configuration and the carried part."""

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
        follow = then if then is not None and then.kind in ("descend", "linear", "align") else None
        return (
            step.index,
            step.kind,
            step.name,
            repr(step.args),
            _bytes(step.T_world_tcp),
            step.q_goal_deg,
            _bytes(goal_q),
            allowances,
            None
            if follow is None
            # a look's branch depends on the align's box (its correcting lines)
            else (follow.kind, _bytes(follow.T_world_tcp), repr(follow.args))
            if follow.kind == StepKind.ALIGN
            else (follow.kind, _bytes(follow.T_world_tcp)),
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
            collision = self.collision()
            # sampled only: verification proves the timed trajectory, and a move that fails
            # it is planned again proven (_prove_sampled)
            head = self.q[None, :]
            if egress is not None:
                head = plan_linear(kin, collision, self.q, egress[0]).q_rad
                row.message = egress[1]
            if goal_q is None:
                assert step.T_world_tcp is not None  # a move has a joint or a frame target
                goal_q, (path, loose) = self._reach_a_branch(
                    collision, head, self._ik(step.T_world_tcp, step, then)
                )
            else:
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
            path = self._line_path(step, collision, T_goal)
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

    def _reach_a_branch(
        self, collision: CollisionModel, head: np.ndarray, branches: Iterator[np.ndarray]
    ) -> tuple[np.ndarray, tuple[np.ndarray, Callable[[], np.ndarray] | None]]:
        """The first of ``branches`` (in :meth:`_ik`'s order) a joint path reaches from
        ``head``, and that path: the nearest branch may lie where no path leads (on a
        wall, beyond the plate the upper arm would have to pass through) while another
        one is reached. When none is, the nearest branch's error."""
        first: InfeasibleError | None = None
        for q in itertools.islice(branches, MAX_GOAL_BRANCHES):
            try:
                return q, _sampled_joint_path(collision, head, q)
            except InfeasibleError as exc:
                if not exc.failure.reason.startswith("no collision-free joint path"):
                    raise
                first = first or exc
        assert first is not None  # _ik returns at least one branch
        raise first

    def _ik(self, T_world_tcp: np.ndarray, step: Step, then: Step | None) -> Iterator[np.ndarray]:
        """The branches to try, in order: those nearest the current configuration that
        are collision-free and, when a straight descend follows, from which that descend
        runs clear to its goal on the same branch (else the nearest whose descend's goal
        is clear, else the nearest collision-free one)."""
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
        if then is not None and then.kind == StepKind.ALIGN:
            from cellrunner.planning.align_correction import correcting_goals

            # the look: the nearest branch from which every correcting line the run time
            # may make there plans clear (near the wrist singularity the nearest may fail
            # where a branch on the other shoulder side clears them all)
            goals = correcting_goals(then, T_world_tcp)
            sure = (
                np.asarray(q)
                for q in valid
                if all(_line_plans(kin, collision, np.asarray(q), T) for T in goals)
            )
            nearest = next(sure, None)
            if nearest is not None:
                return itertools.chain([nearest], sure)
            return iter([np.asarray(valid[0])])  # the align will say which correction fails
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
            # the branches whose whole line down is clear: another branch's descend may
            # pass an arm link by a fixture on its way (issue 33)
            # (each further one's line planned only if the ones before it are not reached)
            clear = (np.asarray(q) for q, after in ends_clear if _line_plans(kin, after, q, follow))
            nearest = next(clear, None)
            if nearest is not None:
                return itertools.chain([nearest], clear)
            # else the descend will say what is in the way, or what is wrong with it
            return iter([np.asarray(ends_clear[0][0] if ends_clear else valid[0])])
        return (np.asarray(q) for q in valid)

    def _line_path(self, step: Step, collision: CollisionModel, T_goal: np.ndarray) -> np.ndarray:
        """The joint samples of the straight line to ``T_goal``, clear in ``collision``. A
        line refused for pressing into a fixture its step names in ``contact:`` further
        than the contact allows is refused for what that is, where the step's fit rules
        find it (a tip over a rim or a chamfer, an interference fit: a jam)."""
        from cellrunner.planning.cartesian import plan_linear

        kin = self.world.kinematics
        try:
            return plan_linear(kin, collision, self.q, T_goal).q_rad
        except InfeasibleError as exc:
            named = set(getattr(step.args, "contact", None) or ())
            if exc.failure.kind is not FailureKind.COLLISION or not any(
                b.body.kind is BodyKind.FIXTURE and b.body.name in named
                for b in exc.failure.blockers
            ):
                raise
            free = plan_linear(kin, None, self.q, T_goal).q_rad
            kind_of(step.kind).check_line(self, step, free)  # raises the fit's refusal
            raise

    def _linear_goal(self, step: Step, T_now: np.ndarray) -> np.ndarray:
        return kind_of(step.kind).line_goal(self, step, T_now)


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


def sets_down(step: Step, world: CellWorld | None = None) -> bool:
    """Whether ``step`` comes down onto something, timed at ``SET_DOWN_TCP_ACCEL_MPS2``:
    a place's descend (the part onto its support), or a pick's with suction cups (the
    cups onto the part's face; jaws come down around a part, touching nothing), or a
    descend into the fixtures its ``contact:`` names (a pin to the mouth of its hole:
    braking at the joints' limits there, a UR10e's TCP lagged 0.6 mm sideways, over the
    0.46 mm the pin had to its walls, and the pin landed on the rim, 570 N)."""
    if step.kind != StepKind.DESCEND:
        return False
    if step.macro_kind == "place" or getattr(step.args, "contact", None):
        return True
    gripper = world.loaded.cell.tool.gripper if world is not None else None
    return step.macro_kind == "pick" and gripper is not None and gripper.kind == "vacuum"
