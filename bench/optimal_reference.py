"""The optimal reference of bench_cycle: for every joint move of a plan, the shortest path
an asymptotically optimal planner finds in a time budget, timed by the same TOPP-RA.

For each ``move``/``approach`` step: our planner's path (its waypoints as planned, the
corners rounded, before the step is blended into its neighbours) and OMPL's BIT* (batch
informed trees) with a path-length objective (joint-space length, rad), searching from
the same start to the same goal in the same collision model (the tool mounted, the part
carried, the cell's clearance), every edge proven by :meth:`CollisionModel.check_motion`,
for ``budget_s``. BIT*'s path gets its corners rounded by proven arcs as ours
(:func:`cellrunner.planning.joint_path.round_corners`), so that neither path is timed
with sharp corners. Both are timed rest to rest by the same continuous TOPP-RA
(:func:`cellrunner.planning.timing.optimal_duration_s`) under the step's limits; blends
between steps are left out of both (they are what bench_cycle's other columns measure).

The reference cycle is cellrunner's cycle with each joint move's time replaced by the
better of the two paths' times (the optimal planner's path, when it found a shorter
one in time; else ours): cellrunner's cycle over it is how far our paths are from the
best collision-free paths known.

Each search takes ``budget_s`` of CPU; results are kept in ``var/bench-optimal.json``
under a key of the move (cell and task digests, step, start, goal, budget), so that a
run that was stopped resumes, and a second run prints at once.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
CACHE = REPO / "var" / "bench-optimal.json"
#: the issue's budget per move (s of search)
BUDGET_S = 10.0


def _load_cache() -> dict[str, Any]:
    try:
        data: dict[str, Any] = json.loads(CACHE.read_text())
        return data
    except (OSError, ValueError):
        return {}


def _save_cache(cache: dict[str, Any]) -> None:
    CACHE.parent.mkdir(parents=True, exist_ok=True)
    tmp = CACHE.with_suffix(".tmp")
    tmp.write_text(json.dumps(cache, indent=1))
    tmp.replace(CACHE)


def bit_star_path(collision, q0: np.ndarray, q1: np.ndarray, budget_s: float, seed: int = 1):
    """The shortest joint path (N x 6) BIT* finds from q0 to q1 in ``budget_s``, every edge
    proven; None when it finds none."""
    from ompl import base as ob
    from ompl import geometric as og

    from cellrunner.planning.joint_path import ompl_problem

    setup, si, _, as_array = ompl_problem(collision, q0, q1, seed)
    setup.setStateValidityChecker(lambda s: collision.is_valid(as_array(s)))

    class Proven(ob.MotionValidator):
        def checkMotion(self, a, b) -> bool:  # OMPL's name
            return collision.check_motion(as_array(a), as_array(b), explain=False).ok

    si.setMotionValidator(Proven(si))
    setup.getProblemDefinition().setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    planner = og.BITstar(si)
    setup.setPlanner(planner)
    try:
        setup.solve(ob.timedPlannerTerminationCondition(budget_s))
        path = (
            np.array([as_array(s) for s in setup.getSolutionPath().getStates()])
            if setup.haveExactSolutionPath()
            else None
        )
    finally:
        setup.setStateValidityChecker(ob.AllValidStateValidityChecker(si))
    if path is not None:
        path[0], path[-1] = q0, q1
    return path


def _length(q: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


def planned_moves(world, steps, q_start) -> list[Any]:
    """The joint moves (``_Motion``: waypoints as planned, collision model, limits, world)
    of the job's steps, planned as ``check`` plans them."""
    from cellrunner.planning import task_plan

    seen: dict[int, Any] = {}
    original = task_plan.StepPlanner.motion

    def recording(self, row, *args, **kwargs):
        motion = original(self, row, *args, **kwargs)
        if row.step.kind in ("move", "approach"):
            seen.setdefault(row.step.index, motion)
        return motion

    task_plan.StepPlanner.motion = recording
    try:
        task_plan.plan_task(world, steps, q_start)
    finally:
        task_plan.StepPlanner.motion = original
    out = []
    for _, motion in sorted(seen.items()):
        q = np.asarray(motion.waypoints, float)  # after any proven replanning
        if len(q) >= 2 and float(np.abs(q[-1] - q[0]).max()) > 1e-6:
            out.append(motion)
    return out


def reference(
    world, plan, steps, digest: str, budget_s: float = BUDGET_S, verbose: bool = True
) -> dict:
    """Per joint move: our path's and the optimal planner's (length, TOPP-RA time); and the
    reference cycle (module docstring)."""
    from cellrunner.planning.joint_path import round_corners
    from cellrunner.planning.timing import optimal_duration_s

    cache = _load_cache()
    rows = []
    saved_s = 0.0
    for motion in planned_moves(world, steps, world.q_home_rad):
        row, collision, limits = motion.row, motion.collision, motion.limits
        q = np.asarray(motion.waypoints, float)
        kin = motion.world.kinematics
        q0, q1 = q[0], q[-1]
        key = hashlib.sha256(
            f"{digest}|{row.step.index}|{budget_s}".encode()
            + np.round(q0, 9).tobytes()
            + np.round(q1, 9).tobytes()
        ).hexdigest()[:24]
        ours_s = optimal_duration_s(kin, q, limits)
        hit = cache.get(key)
        if hit is None:
            t = time.process_time()
            found = bit_star_path(collision, q0, q1, budget_s)
            search_s = time.process_time() - t
            if found is None:
                hit = {"length": None, "time_s": None, "search_s": search_s}
            else:
                rounded = round_corners(collision, found)
                hit = {
                    "length": _length(found),
                    "time_s": optimal_duration_s(kin, rounded, limits),
                    "search_s": search_s,
                }
            cache[key] = hit
            _save_cache(cache)
        best_s = ours_s if hit["time_s"] is None else min(ours_s, hit["time_s"])
        saved_s += ours_s - best_s
        rows.append(
            {
                "step": row.step.label,
                "ours_length": _length(q),
                "ours_s": ours_s,
                "opt_length": hit["length"],
                "opt_s": hit["time_s"],
            }
        )
        if verbose:
            opt = (
                f"{hit['length']:6.3f} rad {hit['time_s']:6.3f} s"
                if hit["time_s"] is not None
                else "no path in budget"
            )
            print(
                f"      {row.step.label[:44]:44s} ours {_length(q):6.3f} rad {ours_s:6.3f} s"
                f"   BIT* {opt}",
                flush=True,
            )
    cycle = plan.cycle_time_s
    return {"moves": rows, "reference_s": cycle - saved_s, "ratio": cycle / (cycle - saved_s)}
