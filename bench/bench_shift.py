"""How fast a shift rehearses (issue 37): ``dry-run CELL TASK --shift 8h`` of reference
cells with docs/shift-faults.yaml, each run a process of its own as a user runs it
(start-up and planning included). Prints a table: per cell, the median wall time over
runs, the simulated shift over it (how many times faster than real time), the ratio to
the target (an 8-hour shift of the demo in under 10 minutes on 2 cores), the distinct
jobs the twin rehearsed and the jobs of the shift.

    python bench/bench_shift.py [--runs 3] [--hours 8] [--seed 1]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CLI = (sys.executable, "-m", "cellrunner.cli.main")
ENV = {**os.environ, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
CASES = (
    ("demo", "cells/demo_ur5e.yaml", "tasks/pick_place.yaml"),
    ("palletizer", "cells/palletizer_ur10e.yaml", "tasks/palletize.yaml"),
)
TARGET_S = 600.0  # an 8-hour shift of the demo


def shift_once(cell: str, task: str, hours: float, seed: int) -> tuple[float, dict[str, object]]:
    t0 = time.perf_counter()
    out = subprocess.run(
        [
            *CLI,
            "dry-run",
            cell,
            task,
            "--shift",
            f"{hours:g}h",
            "--faults",
            "docs/shift-faults.yaml",
            "--seed",
            str(seed),
            "--json",
        ],
        cwd=REPO,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=3600,
        check=False,
    )
    wall_s = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"{cell}: exit {out.returncode}: {out.stderr[-2000:]}")
    return wall_s, json.loads(out.stdout)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--hours", type=float, default=8.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    rows = []
    for name, cell, task in CASES:
        walls, report = [], {}
        for _ in range(args.runs):
            wall_s, report = shift_once(cell, task, args.hours, args.seed)
            walls.append(wall_s)
        median_s = statistics.median(walls)
        rows.append(
            (
                name,
                median_s,
                args.hours * 3600.0 / median_s,
                median_s / (TARGET_S * args.hours / 8.0),
                report["rehearsed_jobs"],
                report["jobs"],
            )
        )
    print(f"shift of {args.hours:g} h, docs/shift-faults.yaml, seed {args.seed}, {args.runs} runs")
    print(
        f"{'cell':<12}{'median wall s':>15}{'x real time':>13}{'/ target':>10}{'rehearsed':>11}{'jobs':>7}"
    )
    for name, median_s, speed, ratio, rehearsed, jobs in rows:
        print(f"{name:<12}{median_s:>15.1f}{speed:>13.0f}{ratio:>10.2f}{rehearsed:>11}{jobs:>7}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
