"""The planning façade the task-level ``check`` builds on.

Frames and units: poses are 4x4 ``T_world_tcp`` matrices (m), joint states ``q_rad`` (6,),
speeds in m/s; see :mod:`cellrunner.planning.kinematics` for the frames.

Typical use::

    planner = MotionPlanner(spec, T_world_base, T_flange_tcp, tool, fixtures, limits)
    a = planner.plan_joint(q_home, T_world_approach, step_index=1, step_name="approach")
    b = planner.plan_linear(a.q_end_rad, T_world_pick, step_index=2, step_name="descend",
                            speed_mps=0.1, allow=(ContactAllowance("table", "tool"),))
    approved = planner.time_and_verify([a])            # stops at the end of a
    approved += planner.time_and_verify([b])            # a separate, rest-to-rest move
    # after the grip, lift -> transfer -> approach without stopping:
    planner.time_and_verify([lift, transfer, approach])

Errors are :class:`InfeasibleError` with a reason (``plan_*``: without the step prefix,
which the caller adds; ``time_and_verify``: "step N name: ...").
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import Placed
from cellrunner.model.robots import RobotSpec
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory
from cellrunner.planning.cartesian import plan_linear
from cellrunner.planning.collision import CollisionModel, ContactAllowance
from cellrunner.planning.joint_path import plan_joint_path
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.timing import MotionLimits, TimedPath, time_path
from cellrunner.planning.verify import verify_trajectory


@dataclass(frozen=True)
class Segment:
    """One planned, not yet timed, motion: joint waypoints ``q_rad`` (N x 6) to be followed
    by straight joint interpolation (dense for linear moves), the collision world it was
    planned in, its limits, and for linear moves the TCP line (start, goal) in the world."""

    kind: str  # "joint" | "linear"
    q_rad: np.ndarray
    collision: CollisionModel = field(repr=False)
    limits: MotionLimits = field(repr=False)
    step_index: int = 0
    step_name: str = ""
    line_m: tuple[np.ndarray, np.ndarray] | None = None
    planner: str = ""

    @property
    def q_start_rad(self) -> np.ndarray:
        return np.asarray(self.q_rad[0])

    @property
    def q_end_rad(self) -> np.ndarray:
        return np.asarray(self.q_rad[-1])


class MotionPlanner:
    """Plans, times and verifies the arm's motions in one cell.

    ``tool``: shapes in the flange frame; ``fixtures``: shapes in the world; ``limits``:
    the cell's limits x margin (:meth:`MotionLimits.from_cell`); ``clearance_m``: distance
    every checked pair keeps (m); ``time_budget_s``: search budget per planned move.
    """

    def __init__(
        self,
        spec: RobotSpec,
        T_world_base: np.ndarray,
        T_flange_tcp: np.ndarray,
        tool: Sequence[Placed],
        fixtures: Sequence[Placed],
        limits: MotionLimits,
        *,
        clearance_m: float = 0.002,
        time_budget_s: float = 2.0,
        seed: int = 1,
    ) -> None:
        self.spec = spec
        self.kinematics = ArmKinematics(spec, T_world_base, T_flange_tcp)
        self.collision = CollisionModel(self.kinematics, tool, fixtures, clearance_m)
        self.limits = limits
        self.time_budget_s = time_budget_s
        self.seed = seed
        self._worlds: dict[tuple[Any, ...], CollisionModel] = {}

    def world(
        self, carried: Placed | None = None, allow: Sequence[ContactAllowance] = ()
    ) -> CollisionModel:
        """The collision world with ``carried`` (placed in the TCP frame) and allowances."""
        key = (id(carried), tuple(allow))
        model = self._worlds.get(key)
        if model is None:
            model = self.collision.carrying(carried).allowing(*allow)
            self._worlds[key] = model
        return model

    def ik(
        self,
        T_world_tcp: np.ndarray,
        q_near_rad: np.ndarray,
        *,
        carried: Placed | None = None,
        allow: Sequence[ContactAllowance] = (),
    ) -> np.ndarray:
        """The collision-free IK branch nearest ``q_near_rad`` for ``T_world_tcp``."""
        world = self.world(carried, allow)
        solutions = self.kinematics.ik_all(T_world_tcp, q_near_rad)
        if not solutions:
            raise InfeasibleError(self.kinematics.unreachable_reason(T_world_tcp))
        for q in solutions:
            if world.is_valid(q):
                return q
        raise InfeasibleError(
            f"every arm configuration reaching the pose collides ({len(solutions)} IK solutions; "
            f"nearest: {world.clearance(solutions[0]).describe()})"
        )

    def plan_joint(
        self,
        q_start_rad: np.ndarray,
        goal: np.ndarray,
        *,
        carried: Placed | None = None,
        allow: Sequence[ContactAllowance] = (),
        speed_fraction: float = 1.0,
        step_index: int = 0,
        step_name: str = "",
    ) -> Segment:
        """A collision-free joint move to ``goal``: six joint angles (rad) or a 4x4
        ``T_world_tcp`` (solved on the collision-free IK branch nearest the start)."""
        world = self.world(carried, allow)
        goal = np.asarray(goal, float)
        q_goal = (
            self.ik(goal, q_start_rad, carried=carried, allow=allow)
            if goal.shape == (4, 4)
            else goal
        )
        path = plan_joint_path(
            world, q_start_rad, q_goal, time_budget_s=self.time_budget_s, seed=self.seed
        )
        return Segment(
            "joint",
            path.q_rad,
            world,
            self.limits.scaled(speed_fraction),
            step_index,
            step_name,
            None,
            path.planner,
        )

    def plan_linear(
        self,
        q_start_rad: np.ndarray,
        T_world_tcp_goal: np.ndarray,
        *,
        speed_mps: float | None = None,
        carried: Placed | None = None,
        allow: Sequence[ContactAllowance] = (),
        step_index: int = 0,
        step_name: str = "",
    ) -> Segment:
        """A straight TCP line from FK(q_start) to ``T_world_tcp_goal`` at most ``speed_mps``."""
        world = self.world(carried, allow)
        path = plan_linear(self.kinematics, world, q_start_rad, T_world_tcp_goal)
        return Segment(
            "linear",
            path.q_rad,
            world,
            self.limits.scaled(1.0, speed_mps),
            step_index,
            step_name,
            (path.p_start_m, path.p_goal_m),
            "linear",
        )

    def time_and_verify(
        self,
        segments: Sequence[Segment],
        *,
        previous: ApprovedTrajectory | None = None,
    ) -> list[ApprovedTrajectory]:
        """Time ``segments`` as one non-stop motion (rest at its start and end only), split
        it back into one approved trajectory per segment, each verified independently.

        The joined motion uses the slowest limits of its segments. When joining fails
        verification (e.g. a corner rounded off a linear step), the segments are timed
        rest-to-rest one by one instead. ``previous``: the step before, for continuity.
        """
        if not segments:
            return []
        if len(segments) > 1:
            try:
                return self._timed(segments, previous)
            except InfeasibleError:
                pass
        out: list[ApprovedTrajectory] = []
        for segment in segments:
            out += self._timed([segment], previous)
            previous = out[-1]
        return out

    def _timed(
        self, segments: Sequence[Segment], previous: ApprovedTrajectory | None
    ) -> list[ApprovedTrajectory]:
        waypoints = [segments[0].q_rad]
        for seg in segments[1:]:
            if np.abs(seg.q_rad[0] - waypoints[-1][-1]).max() > 1e-9:
                raise InfeasibleError(
                    f"step {seg.step_index} {seg.step_name}: does not start where the previous motion ends"
                )
            waypoints.append(seg.q_rad[1:])
        junction_index = (
            np.cumsum([len(seg.q_rad) - (0 if i == 0 else 1) for i, seg in enumerate(segments)]) - 1
        )
        limits = MotionLimits(
            np.min([s.limits.joint_speed_rad_s for s in segments], axis=0),
            np.min([s.limits.joint_accel_rad_s2 for s in segments], axis=0),
            min(s.limits.tcp_speed_mps for s in segments),
        )
        timed = time_path(self.kinematics, np.vstack(waypoints), limits, self.spec.rate_hz)
        s_wp = _waypoint_s(np.vstack(waypoints), timed)
        bounds = [0]
        for i, seg in enumerate(segments[:-1]):
            s_j = s_wp[junction_index[i]]
            if seg.kind == "linear":
                k = int(np.searchsorted(timed.s, s_j + 1e-12, side="right")) - 1
            elif segments[i + 1].kind == "linear":
                k = int(np.searchsorted(timed.s, s_j - 1e-12, side="left"))
            else:
                k = int(np.argmin(np.abs(timed.s - s_j)))
            bounds.append(min(max(k, bounds[-1] + 1), len(timed.q_rad) - 1))
        bounds.append(len(timed.q_rad) - 1)
        out: list[ApprovedTrajectory] = []
        prev_q = None if previous is None else previous.trajectory.q_rad[-2:]
        prev_moving = False
        for i, seg in enumerate(segments):
            q = timed.q_rad[bounds[i] : bounds[i + 1] + 1]
            traj = Trajectory(self.spec.rate_hz, np.arange(len(q)) / self.spec.rate_hz, q)
            approved = verify_trajectory(
                traj,
                step_index=seg.step_index,
                step_name=seg.step_name,
                kinematics=self.kinematics,
                limits=limits,
                collision=seg.collision,
                previous_q_rad=prev_q if prev_q is not None else seg.q_start_rad,
                previous_moving=prev_moving,
                ends_at_rest=i == len(segments) - 1,
                line_m=seg.line_m,
            )
            out.append(approved)
            prev_q = q[-2:] if len(q) >= 2 else q
            prev_moving = True
        return out


def _waypoint_s(waypoints: np.ndarray, timed: TimedPath) -> np.ndarray:
    """Path position s of every input waypoint (duplicates collapsed as time_path does)."""
    s = [0.0]
    for a, b in itertools.pairwise(waypoints):
        s.append(s[-1] + float(np.linalg.norm(b - a)))
    return np.array(s)
