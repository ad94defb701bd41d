"""Wall time of ``cellrunner check`` as a user runs it: cold (no plan cache) and warm.

Run: ``python bench/bench_check.py [--cold 3] [--warm 5]`` from the repository root, or
``python bench/run_all.py``.

Each run is a whole fresh process, ``python -m cellrunner.cli.main check CELL TASK --json``
(what the ``cellrunner`` script runs), timed from spawn to exit with time.perf_counter:

- cold: ``--no-cache``: every slot of the pattern is planned and verified;
- warm: the plan cache under ``var/plan-cache/`` is populated by one run first, then each
  run reads the approved plans back (they stay unsealed until first use).

Also timed, to show where a warm run's time goes: the bare interpreter, and the imports a
check needs (the CLI, the cell/task model, the plan cache). Medians over the runs.
Target: warm < 1 s.
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
CELL, TASK = "cells/demo_ur5e.yaml", "tasks/pick_place.yaml"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def timed(args: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=REPO, env=_env(), capture_output=True, text=True)
    return time.perf_counter() - t, done


def check_args(*extra: str) -> list[str]:
    return ["-m", "cellrunner.cli.main", "check", CELL, TASK, "--json", *extra]


def run(cold_runs: int = 3, warm_runs: int = 5, verbose: bool = True) -> dict:
    cold = []
    for _ in range(cold_runs):
        t, done = timed(check_args("--no-cache"))
        if done.returncode != 0:
            raise SystemExit(f"check failed (exit {done.returncode}): {done.stderr.strip()[-500:]}")
        cold.append(t)
        if verbose:
            print(f"  cold  {t:6.2f} s", flush=True)
    _, done = timed(check_args())  # populate the cache
    cycle = json.loads(done.stdout)["cycle_time_s"]
    warm = []
    for _ in range(warm_runs):
        t, done = timed(check_args())
        warm.append(t)
        if verbose:
            print(f"  warm  {t:6.2f} s", flush=True)
    bare = statistics.median(timed(["-c", "pass"])[0] for _ in range(3))
    imports = statistics.median(
        timed(["-c", "import cellrunner.cli.main, cellrunner.cli.cmd_check, cellrunner.cli.common, "
                     "cellrunner.planning.cache, cellrunner.planning.collision"])[0] for _ in range(3))
    return {"cold_s": statistics.median(cold), "warm_s": statistics.median(warm), "cold_runs": cold_runs,
            "warm_runs": warm_runs, "interpreter_s": bare, "imports_s": imports, "cycle_time_s": cycle}


def summary_lines(r: dict) -> list[str]:
    return [
        f"check wall time, {CELL} {TASK} (whole process, median):",
        f"  cold (--no-cache, {r['cold_runs']} runs)  {r['cold_s']:6.2f} s",
        f"  warm (plan cache, {r['warm_runs']} runs)  {r['warm_s']:6.2f} s   (target < 1 s; of which "
        f"interpreter {r['interpreter_s']:.2f} s, imports to {r['imports_s']:.2f} s)",
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cold", type=int, default=3, help="cold runs")
    parser.add_argument("--warm", type=int, default=5, help="warm runs")
    args = parser.parse_args(argv)
    result = run(args.cold, args.warm)
    print()
    print("\n".join(summary_lines(result)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
