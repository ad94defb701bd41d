"""The cycle bench's PolyScope program is taught the planner's waypoints with the corners
left sharp (bench/bench_cycle.py): planning without arcs must reach the planner's own path,
or the program gets every arc point as a via point and its time is charged for them."""

from __future__ import annotations

import contextlib
import io
import sys

from tests.conftest import ROOT


def test_the_cycle_bench_teaches_sharp_corners():
    sys.path.insert(0, str(ROOT / "bench"))
    try:
        import bench_cycle
    finally:
        sys.path.remove(str(ROOT / "bench"))
    from cellrunner.cli.common import load, parse_params
    from cellrunner.model.expand import expand
    from cellrunner.planning.joint_path import CORNER_POINTS
    from cellrunner.planning.world import CellWorld

    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml"))
    world = CellWorld(cell)
    steps = expand(task, cell.cell, parse_params([], task))
    taught = bench_cycle.taught_waypoints(world, steps, world.q_home_rad)
    searched = [q for q, _ in taught.values() if len(q) > 2]
    assert searched  # the demo has searched joint moves (around the infeed's guard)
    assert all(len(q) < CORNER_POINTS for q in searched)  # sharp corners, no arc points
