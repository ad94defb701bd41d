"""What ``check``'s proof of tracked steps costs, and what it finds, on the reference
conveyor cells.

Run: ``python bench/bench_conveyor_check.py [--repeats 5]`` from the repository root.

For each cell (``cells/conveyor_pick_ur10e.yaml``, a belt; ``cells/round_table_ur10e.yaml``,
a round table) the task is planned once (no plan cache), then the proof of its tracked
steps (:func:`cellrunner.planning.tracking.prove_tracking`: every belt speed and start,
reach, limits and collisions sampled every 8 ms) is timed ``--repeats`` times in this
process. Printed: the plan's time, the proof's median, the cases and the median per case,
the proof against the plan, and what the proof finds (the latest start at top speed, the
parts per minute). No target yet: the figures say what a tracked pick adds to check's
time (an IK solution for every sample of every case dominates: about 12 000 for the belt).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CELLS = [
    ("belt", "cells/conveyor_pick_ur10e.yaml", "tasks/conveyor_pick.yaml"),
    ("round table", "cells/round_table_ur10e.yaml", "tasks/round_table_pick.yaml"),
]


def measure(cell_path: str, task_path: str, repeats: int) -> dict[str, float]:
    from cellrunner.model.expand import expand, resolve_params
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.task_plan import plan_task
    from cellrunner.planning.tracking import prove_tracking
    from cellrunner.planning.world import CellWorld

    cell = load_cell(REPO / cell_path)
    task = load_task(REPO / task_path, cell)
    steps = expand(task, cell.cell, resolve_params(task.task, {}))
    world = CellWorld(cell)
    t0 = time.perf_counter()
    plan = plan_task(world, steps, world.q_home_rad)
    plan_s = time.perf_counter() - t0
    assert plan.ok, plan.errors
    times, proof = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        (proof,) = prove_tracking(world, plan)
        times.append(time.perf_counter() - t0)
    assert proof is not None
    proof_s = statistics.median(times)
    return {
        "plan_s": plan_s,
        "proof_s": proof_s,
        "cases": len(proof.cases),
        "ms_per_case": 1000 * proof_s / max(1, len(proof.cases)),
        "ratio": proof_s / plan_s,
        "latest_m": proof.latest_start_m if proof.latest_start_m is not None else float("nan"),
        "ppm": proof.parts_per_minute,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO))
    print(
        f"{'cell':<12} {'plan s':>7} {'proof s':>8} {'cases':>6} {'ms/case':>8} "
        f"{'proof/plan':>10} {'latest m':>9} {'parts/min':>9}"
    )
    for name, cell, task in CELLS:
        m = measure(cell, task, args.repeats)
        print(
            f"{name:<12} {m['plan_s']:>7.2f} {m['proof_s']:>8.2f} {m['cases']:>6.0f} "
            f"{m['ms_per_case']:>8.1f} {m['ratio']:>10.2f} {m['latest_m']:>+9.3f} {m['ppm']:>9.1f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
