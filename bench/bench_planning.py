"""Joint-planning benchmark: cellrunner's planner vs pyroboplan's RRT on the same problems.

Run: ``python bench/bench_planning.py`` (from the repository root). Scenes: bench/scenes.py
(UR5e, cluttered table, shelf, bins). Each problem is solved by both planners in this run
on the identical pinocchio model and collision geometry (pairs and capsules); pyroboplan
runs its bidirectional RRT-Connect with a 0.05 rad discrete edge check and a padding equal
to our clearance; its time excludes path shortening, ours includes it.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from scenes import HOME_DEG, T_FLANGE_TCP, scenes, tool  # noqa: E402

from cellrunner.errors import InfeasibleError  # noqa: E402
from cellrunner.model.robots import robot_spec  # noqa: E402
from cellrunner.planning.collision import CollisionModel  # noqa: E402
from cellrunner.planning.joint_path import plan_joint_path  # noqa: E402
from cellrunner.planning.kinematics import ArmKinematics  # noqa: E402

CLEARANCE_M = 0.002


def problems():
    kin = ArmKinematics(robot_spec("ur5e"), np.eye(4), T_FLANGE_TCP)
    home = np.radians(HOME_DEG)
    for scene in scenes():
        world = CollisionModel(kin, tool(), scene.fixtures, CLEARANCE_M)
        q = {}
        for name, T in scene.targets:
            valid = [s for s in kin.ik_all(T, home) if world.is_valid(s)]
            if valid:
                q[name] = valid[0]
        for a, b in scene.problems:
            if a in q and b in q:
                yield f"{scene.name}:{a}->{b}", kin, world, q[a], q[b]
            else:
                print(f"  (skipped {scene.name}:{a}->{b}: no collision-free IK)")


def ours(world, q0, q1):
    t = time.perf_counter()
    try:
        path = plan_joint_path(world, q0, q1, time_budget_s=5.0, seed=1)
    except InfeasibleError:
        return None, time.perf_counter() - t
    return path, time.perf_counter() - t


def pyroboplan_runner():
    try:
        from pyroboplan.planning.rrt import RRTPlanner, RRTPlannerOptions
    except Exception as exc:  # report exactly why the baseline is missing
        return None, f"pyroboplan unavailable: {type(exc).__name__}: {exc}"

    def run(kin, world, q0, q1):
        options = RRTPlannerOptions(
            max_step_size=0.05, rrt_connect=True, bidirectional_rrt=True,
            max_planning_time=10.0, rng_seed=1, collision_distance_padding=CLEARANCE_M,
        )
        planner = RRTPlanner(kin.model, world.pinocchio_geometry, options)
        t = time.perf_counter()
        path = planner.plan(q0, q1)
        return path, time.perf_counter() - t

    return run, ""


def main() -> int:
    rows = []
    baseline, why = pyroboplan_runner()
    for name, kin, world, q0, q1 in problems():
        path, t_ours = ours(world, q0, q1)
        t_base, ok_base = None, None
        if baseline is not None:
            try:
                base_path, t_base = baseline(kin, world, q0, q1)
                ok_base = base_path is not None
            except Exception as exc:
                why = f"pyroboplan failed: {type(exc).__name__}: {exc}"
                baseline = None
        rows.append((name, path, t_ours, ok_base, t_base))
        how = path.planner if path is not None else "FAIL"
        base = "" if t_base is None else f"{t_base * 1000:9.1f} ms {'ok' if ok_base else 'FAIL'}"
        print(f"{name:32s} {how:10s} {t_ours * 1000:8.1f} ms   {base}")
    ok = [r for r in rows if r[1] is not None]
    times = [r[2] for r in rows]
    print()
    print(f"problems: {len(rows)} (UR5e, table/shelf/bin scenes)")
    print(f"cellrunner   success {len(ok)}/{len(rows)}  median {statistics.median(times) * 1000:7.1f} ms  "
          f"p95 {np.percentile(times, 95) * 1000:7.1f} ms  "
          f"(direct {sum(1 for r in ok if r[1].planner == 'direct')}, rrtconnect {sum(1 for r in ok if r[1].planner != 'direct')})")
    base_times = [r[4] for r in rows if r[4] is not None]
    if base_times:
        base_ok = sum(1 for r in rows if r[3])
        print(f"pyroboplan   success {base_ok}/{len(rows)}  median {statistics.median(base_times) * 1000:7.1f} ms  "
              f"p95 {np.percentile(base_times, 95) * 1000:7.1f} ms")
        print(f"ratio (pyroboplan median / cellrunner median): {statistics.median(base_times) / statistics.median(times):.1f}x")
    else:
        print(f"pyroboplan   not run: {why}")
    return 0 if len(ok) == len(rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
