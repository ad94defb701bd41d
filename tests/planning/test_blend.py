"""Blends in a task plan: joint moves and straight steps meet without stopping, the arc
is collision-checked, the straight end stays straight, and it pays off in time."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from cellrunner.cli.common import load, parse_params
from cellrunner.model.expand import expand
from cellrunner.planning import corner_blend, group_timing, task_plan
from cellrunner.planning.collision import MotionCheck
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT


@pytest.fixture(scope="module")
def demo():
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml"))
    world = CellWorld(cell)
    steps = expand(task, cell.cell, parse_params(["slot=5"], task))
    plan = task_plan.plan_task(world, steps, world.q_home_rad)
    assert plan.ok, plan.errors
    return world, steps, plan


def _row(plan, kind, n=1):
    return [r for r in plan.rows if r.step.kind == kind][n - 1]


def _speed_rad_s(q: np.ndarray, rate_hz: float) -> float:
    return float(np.abs(q[-1] - q[-2]).max() * rate_hz)


def test_approach_runs_into_the_descend_and_the_rest_of_the_descend_is_straight(demo):
    world, _, plan = demo
    kin, rate = world.kinematics, world.spec.rate_hz
    for n in (1,):  # the pick's; the place's sets its part down from rest (below)
        approach, descend = _row(plan, "approach", n), _row(plan, "descend", n)
        assert approach.verify_inputs["ends_at_rest"] is False
        assert descend.verify_inputs["previous_moving"] is True
        assert _speed_rad_s(approach.trajectory.q_rad, rate) > 0.05  # no stop at the approach point
        # the descend's line starts below the approach point, by at most 40 % of its 100 mm
        top = descend.step.T_world_tcp[:3, 3] + np.array([0, 0, 0.10])
        start, goal = (np.asarray(p) for p in descend.verify_inputs["line_m"])
        assert np.allclose(goal, descend.step.T_world_tcp[:3, 3], atol=1e-6)
        assert 0.005 < np.linalg.norm(top - start) <= 0.04 + 1e-6
        p = kin.p_world_tcp_many(descend.trajectory.q_rad)
        assert np.abs(p[:, :2] - goal[:2]).max() < 0.001  # straight down, within 1 mm


def test_a_weighed_lift_ends_at_rest_and_the_retreat_runs_into_the_move_home(demo):
    world, _, plan = demo
    lift, retreat = _row(plan, "lift"), _row(plan, "retreat")
    assert lift.verify_inputs["ends_at_rest"] is True  # the part is weighed standing still
    assert retreat.verify_inputs["ends_at_rest"] is False
    assert _speed_rad_s(retreat.trajectory.q_rad, world.spec.rate_hz) > 0.05


def test_a_place_sets_its_part_down_from_rest_and_gently(demo):
    """A place's descend brakes onto the support at the set-down acceleration, not at the
    joints' limits: a heavy arm's tracking at a 40 m/s^2 stop pressed the part into its
    table in the twin (issue 33)."""
    world, _, plan = demo
    approach, descend = _row(plan, "approach", 2), _row(plan, "descend", 2)
    assert approach.verify_inputs["ends_at_rest"] is True
    assert descend.verify_inputs["previous_moving"] is False
    p = world.kinematics.p_world_tcp_many(descend.trajectory.q_rad)
    v = np.diff(p, axis=0) * world.spec.rate_hz
    a = np.linalg.norm(np.diff(v, axis=0), axis=1) * world.spec.rate_hz
    assert a.max() <= task_plan.SET_DOWN_TCP_ACCEL_MPS2 * 1.3  # the chord's estimate


def test_blends_pay_off(demo):
    world, _steps, plan = demo
    joined = _row(plan, "approach", 1), _row(plan, "descend", 1)
    rest_to_rest = 0.0
    q = joined[0].trajectory.q_rad[0]
    planner = task_plan.StepPlanner(world, q, joined[0].carrying)
    for row in joined:
        motion = planner.motion(task_plan.StepPlan(row.step), goal_q=None)
        piece = group_timing._timed_pieces(world, [motion], q)[0]
        rest_to_rest += (len(piece["trajectory"].q_rad) - 1) / world.spec.rate_hz
        q = piece["trajectory"].q_rad[-1]
    blended = sum(r.duration_s for r in joined)
    assert blended < rest_to_rest - 0.1


def test_no_blend_where_the_arc_is_not_collision_free(demo, monkeypatch):
    world, _steps, plan = demo
    approach, descend = _row(plan, "approach", 2), _row(plan, "descend", 2)
    q0 = approach.trajectory.q_rad[0]
    planner = task_plan.StepPlanner(world, q0, approach.carrying)
    first = planner.motion(task_plan.StepPlan(approach.step), goal_q=None)
    second = planner.motion(task_plan.StepPlan(descend.step), goal_q=None)
    blended = corner_blend._blend(world, [first, second])
    assert len(blended[1].waypoints) < len(second.waypoints)  # the line was shortened
    monkeypatch.setattr(type(first.collision), "check_path", lambda self, q: MotionCheck(ok=False))
    sharp = corner_blend._blend(world, [first, second])
    assert np.array_equal(sharp[0].waypoints, first.waypoints)
    assert np.array_equal(sharp[1].waypoints, second.waypoints)
    assert sharp[1].line_m is second.line_m


def test_a_slot_planned_again_shares_its_motions_timed_once(demo):
    world, _, plan = demo
    from cellrunner.cli.common import load as load_files

    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load_files(
            str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml")
        )
    other = task_plan.plan_task(
        world, expand(task, cell.cell, parse_params(["slot=2"], task)), world.q_home_rad
    )
    assert other.ok
    # the pick is the same for every slot: the same waypoints; each slot plans in its own
    # world (the blocks of the slots before it lie on the pallet), so it is timed there
    assert np.array_equal(
        _row(other, "descend", 1).trajectory.q_rad, _row(plan, "descend", 1).trajectory.q_rad
    )
    # the same slot again: the same verified pieces, not timed again
    again = task_plan.plan_task(
        world, expand(task, cell.cell, parse_params(["slot=2"], task)), world.q_home_rad
    )
    assert _row(again, "descend", 1).approved is _row(other, "descend", 1).approved
    # the place differs
    assert not np.array_equal(
        _row(other, "descend", 2).trajectory.q_rad, _row(plan, "descend", 2).trajectory.q_rad
    )
    # another cell object (its own collision models) times afresh
    fresh = task_plan.plan_task(
        CellWorld(cell), expand(task, cell.cell, parse_params(["slot=5"], task)), world.q_home_rad
    )
    assert _row(fresh, "descend", 1).approved is not _row(plan, "descend", 1).approved
    assert np.array_equal(
        _row(fresh, "descend", 1).trajectory.q_rad, _row(plan, "descend", 1).trajectory.q_rad
    )
