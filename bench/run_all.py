"""Every benchmark in one command, then the summary lines for the README.

Run from the repository root::

    PYTHONPATH=. python bench/run_all.py [--quick] [--all]

1. planning: 20 UR5e problems, cellrunner vs pyroboplan RRT-Connect (bench_planning.py);
2. cycle time of every reference cell's tasks vs the same job as a PolyScope program at
   the same limits, blended and stopping at every waypoint, and vs the time-optimal bound
   on cellrunner's own path (bench_cycle.py, model in bench/polyscope.py);
3. ``cellrunner check`` wall time, cold and warm, ``validate``, and re-verifying a cached
   plan (bench_check.py).

``--all`` then runs the others, each as its own process: the dry-run real-time factor and
planned-vs-simulated cycle (bench_dryrun.py), the PLC soak of 200 Modbus jobs on the real
engine and twin with random faults (bench_plc.py), and servoJ streaming through ur_rtde
into the virtual controller (bench_servo.py).

``--quick`` does fewer repetitions (1 planning run per problem, 1 cold and 3 warm checks).
Exit status 1 when a target is missed: planning 100% success, median <= 5 ms, >= 15x
pyroboplan; cycle <= 0.95x PolyScope blended, <= 0.85x stopping, <= 1.02x the bound on
every cell; cold check <= 1.5 s, warm <= 0.3 s, validate <= 0.25 s, re-verify <= 1 ms
per step.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import bench_check  # noqa: E402
import bench_cycle  # noqa: E402
import bench_planning  # noqa: E402


def targets(planning: dict, cycle: list[dict], check: dict) -> list[tuple[str, bool]]:
    return [
        ("planning success 100%", planning["ours_success"] == planning["problems"]),
        ("planning median <= 5 ms", planning["ours_median_ms"] <= 5.0),
        ("planning >= 15x pyroboplan", planning.get("ratio", 0.0) >= 15.0),
        *bench_cycle.targets(cycle),
        *bench_check.targets(check),
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument(
        "--all", action="store_true", help="also the dry-run, PLC soak and servo benches"
    )
    args = parser.parse_args(argv)
    print("== (1) planning", flush=True)
    planning = bench_planning.run(reps=1 if args.quick else 3)
    print("== (2) cycle time", flush=True)
    cycle = bench_cycle.run_all(verbose=False)
    print("== (3) check wall time", flush=True)
    check = bench_check.run(cold_runs=1 if args.quick else 3, warm_runs=3 if args.quick else 5)
    print()
    print("== summary")
    for line in [
        *bench_planning.summary_lines(planning),
        *bench_cycle.summary_lines(cycle),
        *bench_check.summary_lines(check),
    ]:
        print(line)
    results = targets(planning, cycle, check)
    print("targets: " + ", ".join(f"{name} {'met' if ok else 'MISSED'}" for name, ok in results))
    ok = all(good for _, good in results)
    if args.all:
        ok = run_others(args.quick) and ok
    return 0 if ok else 1


def run_others(quick: bool) -> bool:
    """The engine, PLC and servo benches, each in its own process (they own their threads)."""
    import os
    import subprocess

    env = {
        **os.environ,
        "PYTHONPATH": str(HERE.parent),
        "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"),
    }
    runs = [
        ("(4) dry-run", ["bench_dryrun.py", "--runs", "3" if quick else "5"]),
        (
            "(5) PLC soak",
            [
                "bench_plc.py",
                "--cell",
                "bench.soak_engine:make",
                "--jobs",
                "50" if quick else "200",
            ],
        ),
        ("(6) servoJ streaming", ["bench_servo.py"]),
    ]
    ok = True
    for title, argv in runs:
        print(f"\n== {title}", flush=True)
        ok = (
            subprocess.run(
                [sys.executable, str(HERE / argv[0]), *argv[1:]], cwd=HERE.parent, env=env
            ).returncode
            == 0
            and ok
        )
    return ok


if __name__ == "__main__":
    raise SystemExit(main())
