"""Cycle-time benchmark: the demo task as cellrunner plans it vs a PolyScope program.

Run: ``python bench/bench_cycle.py [CELL TASK]`` from the repository root (defaults:
cells/demo_ur5e.yaml tasks/pick_place.yaml, default params), or ``python bench/run_all.py``.

Three cycle times of the same job:

- **cellrunner**: the planned cycle time of :func:`cellrunner.planning.task_plan.plan_task`
  (what ``check --json`` reports as ``cycle_time_s``): TOPP-RA under the cell's limits x
  margin and TCP cap, lift -> transfer -> approach joined without stopping.
- **PolyScope baseline**: the same waypoints as UR script with the controller defaults,
  stopping at each (no blend radius): every joint waypoint of each ``move``/``approach``
  path of our plan (its goal, and the via points it needs to go around obstacles, since a
  straight ``movej`` to the goal alone would not be collision-free; the path's corners
  as planned, before cellrunner rounds them) as ``movej`` at
  60 deg/s and 80 deg/s^2, each a trapezoid (triangle when short) on the leading joint,
  the others scaled to finish together, as the controller does; every linear step
  (descend, lift, retreat, linear) as one ``movel`` at 250 mm/s and 1200 mm/s^2, a
  trapezoid on the TCP path length (these steps do not turn the tool). Grip, release, IO
  and waits take the same time as in our plan.
- **rest-to-rest**: our waypoints and the cell's limits, but every step timed on its own
  from rest to rest (TOPP-RA per step, no joining).

Target: cellrunner <= 0.7 x the PolyScope baseline.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# UR controller defaults of movej / movel (URScript manual)
MOVEJ_SPEED_DEG_S = 60.0
MOVEJ_ACCEL_DEG_S2 = 80.0
MOVEL_SPEED_MPS = 0.250
MOVEL_ACCEL_MPS2 = 1.2


def trapezoid_s(distance: float, speed: float, accel: float) -> float:
    """Duration of a rest-to-rest move of ``distance`` with a trapezoidal speed profile
    (cruise at ``speed``), or a triangular one when the distance is too short to reach it."""
    distance = abs(float(distance))
    if distance == 0.0:
        return 0.0
    if distance >= speed * speed / accel:
        return distance / speed + speed / accel
    return 2.0 * math.sqrt(distance / accel)


def movej_s(q_from_rad: np.ndarray, q_to_rad: np.ndarray) -> float:
    """``movej`` with the default speed and acceleration: the leading joint's trapezoid."""
    lead = float(np.abs(np.asarray(q_to_rad) - np.asarray(q_from_rad)).max())
    return trapezoid_s(lead, math.radians(MOVEJ_SPEED_DEG_S), math.radians(MOVEJ_ACCEL_DEG_S2))


def movel_s(p_from_m: np.ndarray, p_to_m: np.ndarray) -> float:
    """``movel`` with the default speed and acceleration: a trapezoid on the TCP path."""
    return trapezoid_s(float(np.linalg.norm(np.asarray(p_to_m) - np.asarray(p_from_m))),
                       MOVEL_SPEED_MPS, MOVEL_ACCEL_MPS2)


def plan_with_waypoints(world, steps, q_start, *, rounded: bool = True):
    """``plan_task`` and, per motion step (by index), the joint waypoints and limits it was
    timed with (recorded from the planner's own timing calls). ``rounded=False`` plans with
    the corners of the joint paths left sharp: the waypoints a programmer would teach."""
    from cellrunner.planning import joint_path, task_plan

    recorded: dict[int, tuple[np.ndarray, object]] = {}
    original, original_round = task_plan._timed_pieces, joint_path.round_corners

    def recording(world_, group, q_start_):
        for motion in group:
            # the first timing of a step is the plan's; later ones are its retry path checks
            recorded.setdefault(motion.row.step.index, (np.array(motion.waypoints), motion.limits))
        return original(world_, group, q_start_)

    task_plan._timed_pieces = recording
    if not rounded:
        joint_path.round_corners = lambda collision, q: np.asarray(q, float)
    try:
        t = time.perf_counter()
        plan = task_plan.plan_task(world, steps, q_start)
        plan_s = time.perf_counter() - t
    finally:
        task_plan._timed_pieces, joint_path.round_corners = original, original_round
    return plan, recorded, plan_s


def run(cell_path: str = "cells/demo_ur5e.yaml", task_path: str = "tasks/pick_place.yaml",
        verbose: bool = True) -> dict:
    import contextlib
    import io

    from cellrunner.cli.common import load, parse_params
    from cellrunner.model.expand import LINEAR_KINDS, expand
    from cellrunner.planning.timing import time_path
    from cellrunner.planning.world import CellWorld

    with contextlib.redirect_stderr(io.StringIO()):  # load warnings (e.g. users file)
        cell, task = load(str(REPO / cell_path), str(REPO / task_path))
    params = parse_params([], task)
    world = CellWorld(cell)
    steps = expand(task, cell.cell, params)
    plan, recorded, plan_s = plan_with_waypoints(world, steps, world.q_home_rad)
    if not plan.ok:
        raise SystemExit(f"the task is infeasible: {plan.errors}")
    _, taught, _ = plan_with_waypoints(world, steps, world.q_home_rad, rounded=False)
    kin, rate = world.kinematics, world.spec.rate_hz
    rows = []
    for row in plan.rows:
        step = row.step
        if not step.is_motion:
            rows.append((step, row.duration_s, row.duration_s, row.duration_s, 0, row.duration_s))
            continue
        waypoints, limits = recorded[step.index]
        teach = taught[step.index][0]
        if step.kind in LINEAR_KINDS:
            poly = movel_s(kin.T_world_tcp(teach[0])[:3, 3], kin.T_world_tcp(teach[-1])[:3, 3])
            stops, goals_only = 1, poly
        else:
            poly = sum(movej_s(a, b) for a, b in zip(teach[:-1], teach[1:]))
            stops, goals_only = len(teach) - 1, movej_s(teach[0], teach[-1])
        alone = time_path(kin, waypoints, limits, rate).t_s[-1] if len(waypoints) > 1 else 0.0
        rows.append((step, row.duration_s, poly, float(alone), stops, goals_only))
    ours = sum(r[1] for r in rows)
    polyscope = sum(r[2] for r in rows)
    rest = sum(r[3] for r in rows)
    goals = sum(r[5] for r in rows)
    if verbose:
        print(f"  {'step':34s} {'cellrunner':>10s} {'PolyScope':>10s} {'rest-rest':>10s}")
        for step, a, b, c, stops, _ in rows:
            via = f"  ({stops} movej)" if stops > 1 else ""
            print(f"  {step.label[:34]:34s} {a:9.2f}s {b:9.2f}s {c:9.2f}s{via}")
    return {
        "cell": cell_path, "task": task_path, "params": params,
        "ours_s": ours, "polyscope_s": polyscope, "rest_to_rest_s": rest, "polyscope_goals_only_s": goals,
        "ratio_polyscope": ours / polyscope, "ratio_rest": ours / rest, "plan_s": plan_s,
        "check_cycle_time_s": plan.cycle_time_s,
    }


def summary_lines(r: dict) -> list[str]:
    return [
        f"cycle time, {r['task']} on {r['cell']} (params {r['params']}):",
        f"  cellrunner (planned, joined)        {r['ours_s']:6.2f} s",
        f"  PolyScope movej/movel defaults      {r['polyscope_s']:6.2f} s   cellrunner / PolyScope = "
        f"{r['ratio_polyscope']:.2f}x (target <= 0.70x)",
        f"  same limits, rest-to-rest per step  {r['rest_to_rest_s']:6.2f} s   cellrunner / rest-to-rest = "
        f"{r['ratio_rest']:.2f}x",
        f"  (PolyScope with movej straight to each goal, ignoring the via points that clear the "
        f"obstacles: {r['polyscope_goals_only_s']:.2f} s, ratio {r['ours_s'] / r['polyscope_goals_only_s']:.2f}x)",
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cell", nargs="?", default="cells/demo_ur5e.yaml")
    parser.add_argument("task", nargs="?", default="tasks/pick_place.yaml")
    args = parser.parse_args(argv)
    result = run(args.cell, args.task)
    print()
    print("\n".join(summary_lines(result)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
