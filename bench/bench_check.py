"""Wall time of ``cellrunner check`` as a user runs it: cold (no plan cache) and warm.

Run: ``python bench/bench_check.py [--cold 3] [--warm 5]`` from the repository root, or
``python bench/run_all.py``.

Each run is a whole fresh process, ``python -m cellrunner.cli.main check CELL TASK --json``
(what the ``cellrunner`` script runs), timed from spawn to exit with time.perf_counter:

- cold: ``--no-cache``: every slot of the pattern is planned and verified;
- warm: the plan cache under ``var/plan-cache/`` is populated by one run first, then each
  run reads the approved plans back (they stay unsealed until first use).

Also timed: ``cellrunner validate CELL`` (whole process); re-verifying a cached plan
(in this process: the plan read back from the disk cache, each motion step sealed by
the verifier again, as ``run``/``serve`` do before streaming; per step); and, to show
where a warm run's time goes, the bare interpreter and the imports a check needs (the
CLI, the cell/task model, the plan cache). Medians over the runs.
Targets: cold <= 1.5 s, warm <= 0.3 s, validate <= 0.25 s, re-verify <= 1 ms per step.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CELL, TASK = "cells/demo_ur5e.yaml", "tasks/pick_place.yaml"


def _env() -> dict[str, str]:
    """This environment, with bytecode caching on: an installed cellrunner has its .pyc
    files, and PYTHONDONTWRITEBYTECODE (set on some development machines) would make every
    run compile the whole package from source (0.2 s more per run, measured)."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = str(REPO) + (
        os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else ""
    )
    return env


def timed(args: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    before = _children_cpu_s()
    done = subprocess.run(
        [sys.executable, *args], cwd=REPO, env=_env(), capture_output=True, text=True
    )
    wall = time.perf_counter() - t
    CPU_S.append(_children_cpu_s() - before)
    return wall, done


#: CPU time (user + system, s) of each process :func:`timed` ran, in order: what a run costs
#: without the wait for a core on a loaded machine
CPU_S: list[float] = []


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def check_args(*extra: str) -> list[str]:
    return ["-m", "cellrunner.cli.main", "check", CELL, TASK, "--json", *extra]


def run(cold_runs: int = 3, warm_runs: int = 5, verbose: bool = True) -> dict:
    cold, cold_cpu, warm_cpu = [], [], []
    for _ in range(cold_runs):
        t, done = timed(check_args("--no-cache"))
        cold_cpu.append(CPU_S[-1])
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
        warm_cpu.append(CPU_S[-1])
        if verbose:
            print(f"  warm  {t:6.2f} s", flush=True)
    bare = statistics.median(timed(["-c", "pass"])[0] for _ in range(3))
    imports = statistics.median(
        timed(
            [
                "-c",
                "import cellrunner.cli.main, cellrunner.cli.cmd_check, cellrunner.cli.common, "
                "cellrunner.planning.cache, cellrunner.planning.collision",
            ]
        )[0]
        for _ in range(3)
    )
    validate = statistics.median(
        timed(["-m", "cellrunner.cli.main", "validate", CELL])[0] for _ in range(warm_runs)
    )
    validate_cpu = statistics.median(CPU_S[-warm_runs:])
    return {
        "cold_s": statistics.median(cold),
        "warm_s": statistics.median(warm),
        "cold_cpu_s": statistics.median(cold_cpu),
        "warm_cpu_s": statistics.median(warm_cpu),
        "validate_cpu_s": validate_cpu,
        "load_average": os.getloadavg()[0],
        "cold_runs": cold_runs,
        "warm_runs": warm_runs,
        "interpreter_s": bare,
        "imports_s": imports,
        "cycle_time_s": cycle,
        "validate_s": validate,
        "reverify_ms_per_step": reverify_ms_per_step(),
    }


def reverify_ms_per_step(runs: int = 5) -> float:
    """Median CPU time (ms) to seal one motion step of a plan read back from the disk cache."""
    import contextlib
    import io

    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from cellrunner.cli.common import load, parse_params
    from cellrunner.planning.cache import plan_cached
    from cellrunner.planning.world import CellWorld

    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(REPO / CELL), str(REPO / TASK))
    world = CellWorld(cell)
    params = parse_params([], task)
    plan_cached(world, task, params, world.q_home_rad)  # on disk
    per_step = []
    for _ in range(runs):
        from cellrunner.planning import cache

        cache._MEMORY.clear()
        plan = plan_cached(world, task, params, world.q_home_rad)
        steps = [s for s in plan.steps if s.is_motion]
        t = time.process_time()  # CPU time of this process: other load on the machine left out
        for step in steps:
            assert plan.nominal(step) is not None
        per_step.append((time.process_time() - t) / len(steps) * 1000)
    return statistics.median(per_step)


def summary_lines(r: dict) -> list[str]:
    return [
        f"check wall time, {CELL} {TASK} (whole process, median; CPU = user + system of the "
        f"process; load average {r['load_average']:.1f} on {os.cpu_count()} cores):",
        f"  cold (--no-cache, {r['cold_runs']} runs)  {r['cold_s']:6.2f} s   CPU {r['cold_cpu_s']:5.2f} s"
        "   (target <= 1.5 s)",
        f"  warm (plan cache, {r['warm_runs']} runs)  {r['warm_s']:6.2f} s   CPU {r['warm_cpu_s']:5.2f} s"
        f"   (target <= 0.3 s; bare interpreter {r['interpreter_s']:.2f} s, imports to "
        f"{r['imports_s']:.2f} s)",
        f"  validate                        {r['validate_s']:6.2f} s   CPU {r['validate_cpu_s']:5.2f} s"
        "   (target <= 0.25 s)",
        f"  re-verify a cached plan         {r['reverify_ms_per_step']:6.2f} ms per step, CPU "
        "(target <= 1 ms)",
    ]


def targets(r: dict) -> list[tuple[str, bool]]:
    return [
        ("cold check <= 1.5 s", r["cold_s"] <= 1.5),
        ("warm check <= 0.3 s", r["warm_s"] <= 0.3),
        ("validate <= 0.25 s", r["validate_s"] <= 0.25),
        ("re-verify <= 1 ms/step", r["reverify_ms_per_step"] <= 1.0),
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
