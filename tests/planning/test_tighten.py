"""Via points pulled toward their neighbours' chord (joint_path.tighten): never longer,
every new edge accepted by the check it was given, and the sampled planner keeps the
path before the pull (JointPath.loose) for when the verifier refuses the pulled one."""

from __future__ import annotations

import itertools

import numpy as np

from cellrunner.model.load import load_cell, load_task
from cellrunner.planning import joint_path
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT


def _length(q: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


def _demo_move():
    """The demo's approach from the infeed to the pallet, round the column."""
    cell = load_cell(ROOT / "cells/demo_ur5e.yaml")
    world = CellWorld(cell)
    task = load_task(ROOT / "tasks/pick_place.yaml", cell)
    plan = plan_job(world, task, {"slot": 0}, world.q_home_rad, use_cache=False).task_plan
    row = next(r for r in plan.rows if r.step.kind == "approach" and "pallet" in r.step.name)
    start = next(r for r in plan.rows if r.step.index == row.step.index - 1).q_end_rad
    return world, world.collision.carrying(row.carrying), start, row.q_end_rad


def test_pulled_via_points_shorten_the_path_and_keep_every_edge_free() -> None:
    _, collision, q0, q1 = _demo_move()
    searched = joint_path._rrt_connect(collision, q0, q1, 2.0, 1, conservative=False)
    short = joint_path.shortcut(
        collision, searched, direct_blocked=True, free=joint_path.sampled_free
    )
    assert short is not None and len(short) >= 3  # round the column: via points to pull
    tight = joint_path.tighten(collision, short, joint_path.sampled_free)
    assert _length(tight) < _length(short) - 0.05  # rad: the column's detour cut
    assert np.array_equal(tight[0], q0) and np.array_equal(tight[-1], q1)
    for a, b in itertools.pairwise(tight):
        assert joint_path.sampled_free(collision, a, b)  # the check it was given


def test_the_sampled_planner_keeps_the_loose_path() -> None:
    _, collision, q0, q1 = _demo_move()
    found = joint_path.plan_joint_path(collision, q0, q1, proven=False)
    assert found.planner == "rrtconnect" and found.loose is not None
    loose = found.loose()
    assert np.array_equal(loose[0], q0) and np.array_equal(loose[-1], q1)
    assert _length(loose) > _length(found.q_rad)
