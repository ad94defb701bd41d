"""Wall time of ``cellrunner check`` as a user runs it: cold (no plan cache) and warm.

Run: ``python bench/bench_check.py [--cold 3] [--warm 5]`` from the repository root, or
``python bench/run_all.py``.

Two cells: the demo (a UR5e, 12 pallet slots) and the line-like cell
(``cells/cnc_tray_ur10.yaml``: a CB3 UR10, a 12-slot tray, two tools and a changer, a
force-limited vise insert, door and cycle IO, on_error verified from every state). What
a further slot costs: the line-like cell checked cold with its tray cut to 6 slots and
with all 12, the difference over 6.

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
Targets (issue 27, whole process on 2 cores): the line-like cell cold <= 3 s, the demo
cold <= 1.0 s, a further slot <= 0.1 s, warm <= 0.25 s, validate <= 0.2 s, re-verify
<= 1 ms per step.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CELL, TASK = "cells/demo_ur5e.yaml", "tasks/pick_place.yaml"
LINE_CELL, LINE_TASK = "cells/cnc_tray_ur10.yaml", "tasks/cnc_tray.yaml"


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


def timed(args: list[str], cwd: Path = REPO) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    before = _children_cpu_s()
    done = subprocess.run(
        [sys.executable, *args], cwd=cwd, env=_env(), capture_output=True, text=True
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


def check_args(*extra: str, cell: str = CELL, task: str = TASK) -> list[str]:
    return ["-m", "cellrunner.cli.main", "check", cell, task, "--json", *extra]


def cold_check(
    runs: int, cell: str, task: str, cwd: Path = REPO, verbose: bool = True
) -> tuple[float, float]:
    """Median wall and CPU time (s) of ``runs`` cold checks (``--no-cache``)."""
    wall, cpu = [], []
    for _ in range(runs):
        t, done = timed(check_args("--no-cache", cell=cell, task=task), cwd)
        if done.returncode != 0:
            raise SystemExit(f"check failed (exit {done.returncode}): {done.stderr.strip()[-500:]}")
        wall.append(t)
        cpu.append(CPU_S[-1])
        if verbose:
            print(f"  cold  {cell}  {t:6.2f} s  CPU {cpu[-1]:5.2f} s", flush=True)
    return statistics.median(wall), statistics.median(cpu)


def per_slot(runs: int, verbose: bool = True) -> tuple[float, float]:
    """What one more slot of the line-like cell's tray costs (wall, CPU; s): its cold
    check with 12 slots minus with 6, over 6 (a copy of the project, the param's max cut)."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for folder in ("cells", "tasks"):
            shutil.copytree(REPO / folder, root / folder)
        task = root / LINE_TASK
        text = task.read_text()
        six = text.replace(
            "slot: {type: int, min: 0, max: 11,", "slot: {type: int, min: 0, max: 5,"
        )
        assert six != text
        (root / "tasks" / "cnc_tray_6.yaml").write_text(six)
        w12, c12 = cold_check(runs, LINE_CELL, LINE_TASK, root, verbose)
        w6, c6 = cold_check(runs, LINE_CELL, "tasks/cnc_tray_6.yaml", root, verbose)
    return (w12 - w6) / 6, (c12 - c6) / 6


def run(cold_runs: int = 3, warm_runs: int = 5, verbose: bool = True) -> dict:
    warm_cpu: list[float] = []
    cold_s, cold_cpu_s = cold_check(cold_runs, CELL, TASK, verbose=verbose)
    line_s, line_cpu_s = cold_check(cold_runs, LINE_CELL, LINE_TASK, verbose=verbose)
    slot_s, slot_cpu_s = per_slot(cold_runs, verbose)
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
                "cellrunner.planning.job_plan, cellrunner.planning.collision",
            ]
        )[0]
        for _ in range(3)
    )
    validate = statistics.median(
        timed(["-m", "cellrunner.cli.main", "validate", CELL])[0] for _ in range(warm_runs)
    )
    validate_cpu = statistics.median(CPU_S[-warm_runs:])
    return {
        "cold_s": cold_s,
        "line_s": line_s,
        "line_cpu_s": line_cpu_s,
        "slot_s": slot_s,
        "slot_cpu_s": slot_cpu_s,
        "warm_s": statistics.median(warm),
        "cold_cpu_s": cold_cpu_s,
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
    from cellrunner.planning.job_plan import plan_job
    from cellrunner.planning.world import CellWorld

    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(REPO / CELL), str(REPO / TASK))
    world = CellWorld(cell)
    params = parse_params([], task)
    plan_job(world, task, params, world.q_home_rad)  # on disk
    per_step = []
    for _ in range(runs):
        world.plans.memory.clear()
        plan = plan_job(world, task, params, world.q_home_rad).task_plan
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
        "   (target <= 1.0 s)",
        f"  line-like cell {LINE_CELL}, cold:",
        f"                                  {r['line_s']:6.2f} s   CPU {r['line_cpu_s']:5.2f} s"
        "   (target <= 3 s)",
        f"  a further slot (12 vs 6)        {r['slot_s']:6.3f} s   CPU {r['slot_cpu_s']:5.3f} s"
        "   (target <= 0.1 s)",
        f"  warm (plan cache, {r['warm_runs']} runs)  {r['warm_s']:6.2f} s   CPU {r['warm_cpu_s']:5.2f} s"
        f"   (target <= 0.25 s; bare interpreter {r['interpreter_s']:.2f} s, imports to "
        f"{r['imports_s']:.2f} s)",
        f"  validate                        {r['validate_s']:6.2f} s   CPU {r['validate_cpu_s']:5.2f} s"
        "   (target <= 0.2 s)",
        f"  re-verify a cached plan         {r['reverify_ms_per_step']:6.2f} ms per step, CPU "
        "(target <= 1 ms)",
    ]


def targets(r: dict) -> list[tuple[str, bool]]:
    return [
        ("demo cold check <= 1.0 s", r["cold_s"] <= 1.0),
        ("line-like cold check <= 3 s", r["line_s"] <= 3.0),
        ("a further slot <= 0.1 s", r["slot_s"] <= 0.1),
        ("warm check <= 0.25 s", r["warm_s"] <= 0.25),
        ("validate <= 0.2 s", r["validate_s"] <= 0.2),
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
