"""Every benchmark in one command, then the summary lines for the README.

Run from the repository root::

    PYTHONPATH=. python bench/run_all.py [--quick] [--all]

1. planning: 20 UR5e problems, cellrunner vs pyroboplan RRT-Connect, and 5 each on the
   UR20, UR30, UR5 and UR10 reported beside them (bench_planning.py);
2. cycle time of every reference cell's tasks vs the same job as a PolyScope program at
   the same limits, blended and stopping at every waypoint, and vs the time-optimal bound
   on cellrunner's own path (bench_cycle.py, model in bench/polyscope.py);
3. ``cellrunner check`` wall time, cold and warm, ``validate``, and re-verifying a cached
   plan (bench_check.py).

``--all`` then runs the others, each as its own process: the dry-run real-time factor and
planned-vs-simulated cycle (bench_dryrun.py), the PLC soak of 500 Modbus jobs on the real
engine and twin with random faults, with serve's resident memory after 50 and after 500
(bench_plc.py), and servoJ streaming through ur_rtde into the virtual controller, then
the jog's UDP servo against ``cellrunner twin`` and ``align`` over random part offsets
(bench_servo.py). The last lines are one table of every target.

``--quick`` does fewer repetitions (1 planning run per problem, 1 cold and 3 warm checks,
100 soak jobs).
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

from cellrunner.native_threads import one_thread_each  # noqa: E402

one_thread_each()  # before numpy: the planning bench runs in this process

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
    planning = bench_planning.run(reps=1 if args.quick else 3, large=True)
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
    ok = all(good for _, good in results)
    others: dict = {}
    if args.all:
        ok = run_others(args.quick, others) and ok
    print("\n== targets (medians; every ratio against a peer measured in the same run)")
    print("\n".join(target_table(planning, cycle, check, others)))
    return 0 if ok else 1


def target_table(planning: dict, cycle: list[dict], check: dict, others: dict) -> list[str]:
    """One row per issue-11 target: what was measured, against what, and the verdict."""
    moving = [r for r in cycle if r.get("motion")]
    rows = [("measure", "measured", "peer (same run)", "ratio", "target", "")]

    def row(name, measured, peer, ratio, target, good) -> None:
        rows.append((name, measured, peer, ratio, target, "met" if good else "MISSED"))

    if "ratio" in planning:
        row(
            "planning, 20 UR5e problems (CPU)",
            f"median {planning['ours_median_ms']:.1f} ms",
            f"pyroboplan {planning['base_median_ms']:.1f} ms",
            f"{planning['ratio']:.1f}x",
            ">= 15x, <= 5 ms",
            planning["ratio"] >= 15 and planning["ours_median_ms"] <= 5,
        )
    else:
        row(
            "planning",
            f"median {planning['ours_median_ms']:.1f} ms",
            "pyroboplan MISSING",
            "-",
            ">= 15x",
            False,
        )
    for key, label, limit in (
        ("ratio_blended", "PolyScope blended", bench_cycle.TARGET_BLENDED),
        ("ratio_stopping", "PolyScope stopping", bench_cycle.TARGET_STOPPING),
        ("ratio_bound", "time-optimal bound", bench_cycle.TARGET_BOUND),
    ):
        worst = max((r[key] for r in moving), default=float("nan"))
        row(
            f"cycle, worst of {len(moving)} jobs",
            "",
            label,
            f"{worst:.3f}x",
            f"<= {limit}x",
            worst <= limit,
        )
    for key, cpu, label, limit in (
        ("cold_s", "cold_cpu_s", "check cold, whole process", 1.5),
        ("warm_s", "warm_cpu_s", "check warm, whole process", 0.3),
        ("validate_s", "validate_cpu_s", "validate, whole process", 0.25),
    ):
        row(
            label,
            f"{check[key]:.2f} s (CPU {check[cpu]:.2f} s)",
            f"load {check['load_average']:.1f}",
            "-",
            f"<= {limit} s",
            check[key] <= limit,
        )
    row(
        "re-verify a cached plan (CPU)",
        f"{check['reverify_ms_per_step']:.2f} ms/step",
        "-",
        "-",
        "<= 1 ms",
        check["reverify_ms_per_step"] <= 1.0,
    )
    if "dryrun" in others:
        d = others["dryrun"]
        row(
            "dry-run real-time factor (CPU)",
            f"{min(c['engine_rtf'] for c in d['cases']):.0f}x",
            f"raw mj_step {min(c['mj_step_rtf'] for c in d['cases']):.0f}x",
            f"{d['worst_ratio']:.2f}x",
            ">= 0.8x",
            d["worst_ratio"] >= 0.8,
        )
    if "plc" in others:
        rss = {int(k): v for k, v in others["plc"]["rss_mib"].items()}
        end = max(rss)
        base = rss.get(50, float("nan"))
        row(
            f"serve RSS, {end} jobs vs 50",
            f"{rss[end]:.0f} MiB",
            f"{base:.0f} MiB",
            f"{rss[end] / base:.3f}x",
            "within 10 % at 500",
            end >= 500 and abs(rss[end] / base - 1) <= 0.10,
        )
    widths = [max(len(r[i]) for r in rows) for i in range(6)]
    return ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]


def run_others(quick: bool, results: dict) -> bool:
    """The engine, PLC and servo benches, each in its own process (they own their threads);
    their JSON reports go into ``results`` ("dryrun", "plc")."""
    import json
    import os
    import subprocess
    import tempfile

    env = {
        **os.environ,
        "PYTHONPATH": str(HERE.parent),
        "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable"),
    }
    out = Path(tempfile.mkdtemp(prefix="cellrunner-bench-"))
    runs = [
        ("(4) dry-run", "dryrun", ["bench_dryrun.py", "--runs", "3" if quick else "5"]),
        (
            "(5) PLC soak: serve's cell, engine and twin over Modbus",
            "plc",
            [
                "bench_plc.py",
                "--cell",
                "bench.soak_engine:make",
                "--jobs",
                "100" if quick else "500",
            ],
        ),
        (
            "(6) servoJ streaming, the jog's UDP servo and align",
            None,
            ["bench_servo.py", *(["--udp-probes", "10", "--align-runs", "10"] if quick else [])],
        ),
    ]
    ok = True
    for title, key, argv in runs:
        print(f"\n== {title}", flush=True)
        report = out / f"{key}.json"
        extra = ["--json", str(report)] if key else []
        done = subprocess.run(
            [sys.executable, str(HERE / argv[0]), *argv[1:], *extra], cwd=HERE.parent, env=env
        )
        ok = done.returncode == 0 and ok
        if key and report.is_file():
            results[key] = json.loads(report.read_text())
    return ok


if __name__ == "__main__":
    raise SystemExit(main())
