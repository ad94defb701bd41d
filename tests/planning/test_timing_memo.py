"""The per-cell memo of timed motion groups stays bounded in a long-running ``serve`` (every
job that starts where a fault left the arm adds groups of its own), keeps the groups that
are used again, and a kept plan holds each motion's samples once."""

from __future__ import annotations

import contextlib
import io
import itertools

import numpy as np

from cellrunner.cli.common import load, parse_params
from cellrunner.model.expand import expand
from cellrunner.planning import task_plan
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT


def _load(task: str) -> tuple[CellWorld, object]:
    with contextlib.redirect_stderr(io.StringIO()):
        cell, loaded = load(str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / task))
    return CellWorld(cell), loaded


def test_memo_is_bounded_and_keeps_the_group_used_again() -> None:
    world, task = _load("tasks/home.yaml")
    steps = expand(task, world.loaded.cell, {})
    home = world.q_home_rad
    first = task_plan.plan_task(world, steps, home + np.radians([0, 0, 0, 0, 0, 30]))
    assert first.ok, first.errors
    reused = [r.trajectory for r in first.rows if r.trajectory is not None]
    assert reused
    for k in range(task_plan.TIMING_MEMO_SIZE + 10):  # starts a fault could leave the arm at
        start = home + np.radians([0, 0, 0, 0, 0, -20 + 0.5 * k])
        assert task_plan.plan_task(world, steps, start).ok
        assert len(world.timing_memo) <= task_plan.TIMING_MEMO_SIZE
        if k % 8 == 0:  # the group used again stays (the same verified pieces come back)
            again = task_plan.plan_task(world, steps, home + np.radians([0, 0, 0, 0, 0, 30]))
            assert [r.trajectory for r in again.rows if r.trajectory is not None] == reused


def test_a_joined_motion_keeps_no_view_of_its_whole_group() -> None:
    """A motion that continues another starts from the last samples of that motion's own
    trajectory, not from a view into the group's timed path (which would keep the whole
    group alive beside the pieces, in the memo and in every plan kept in memory)."""
    world, task = _load("tasks/pick_place.yaml")
    steps = expand(task, world.loaded.cell, parse_params(["slot=5"], task))
    plan = task_plan.plan_task(world, steps, world.q_home_rad)
    assert plan.ok, plan.errors
    motions = [r for r in plan.rows if r.trajectory is not None]
    joined = 0
    for before, row in itertools.pairwise(motions):
        assert row.verify_inputs is not None
        if not row.verify_inputs["previous_moving"]:
            continue
        joined += 1
        previous = row.verify_inputs["previous_q_rad"]
        assert previous.base is None or previous.base is before.trajectory.q_rad
    assert joined >= 2
