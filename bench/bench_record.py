"""Does ``--record`` change a job's timing? (issue 36)

The demo cell's pick_place job runs as ``serve`` runs it: the sim backend paced to the
wall clock (``realtime``), the control loop on its own thread at the controller rate.
Each job runs with no recorder, with ``--record`` to .rrd and to .mcap, in turn (``--jobs``
rounds). Measured on the wall clock:

- servo period: the time between two control ticks (an observer stamps each one, first
  in the loop's list), its deviation from the nominal period (ms): median, p99, max;
- heartbeat gap: a thread that, like the PLC server's, wakes every 10 ms to answer the
  heartbeat; the time between two wake-ups (ms): median, p99, max (a GIL held by the
  recorder's worker would show here first).

Ratios are against the job with no recorder. The recorder's worker (posing the scene,
encoding, writing) shares the process and its GIL, as in ``serve`` (which hands the GIL
over every 1 ms: so does this bench).

    PYTHONPATH=. MUJOCO_GL=osmesa python bench/bench_record.py [--jobs 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CELL = ROOT / "cells" / "demo_ur5e.yaml"
TASK = ROOT / "tasks" / "pick_place.yaml"
BEAT_S = 0.010


class TickStamps:
    """A control-loop observer: the wall time of every tick."""

    def __init__(self) -> None:
        self.t: list[float] = []

    def __call__(self, cell: object) -> None:
        self.t.append(time.perf_counter())


def heartbeat(stop: threading.Event, gaps: list[float]) -> None:
    last = time.perf_counter()
    while not stop.is_set():
        time.sleep(BEAT_S)
        now = time.perf_counter()
        gaps.append(now - last)
        last = now


def one_job(mode: str, folder: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """Period deviations (ms), heartbeat gaps (ms) and the job's cycle time (s)."""
    from cellrunner.cli.common import load
    from cellrunner.execution.assembly import assemble_cell
    from cellrunner.record.attach import finish, record_to_file

    cell, task = load(str(CELL), str(TASK))
    assembled = assemble_cell(cell, {1: task}, "sim", realtime=True, warm=True, log=None)
    stamps = TickStamps()
    assembled.loop.observers.insert(0, stamps)
    recorder = None
    if mode != "none":
        recorder = record_to_file(assembled, folder / f"job.{mode}")
    controller, loop = assembled.controller, assembled.loop
    controller.setup()
    stop, gaps = threading.Event(), []
    beat = threading.Thread(target=heartbeat, args=(stop, gaps), daemon=True)
    try:
        loop.step(5)
        assert controller.start_job(1, {"slot": 0}, "", "cli").accepted
        controller.wait_for_plan(timeout_s=600.0) if controller.planning else None
        stamps.t.clear()
        beat.start()
        loop.run_job(max_s=120.0)
    finally:
        stop.set()
        beat.join(1.0)
        controller.close()
        if recorder is not None:
            print(f"  {mode}: {finish(recorder, folder / f'job.{mode}')}")
    job = controller.last_job
    period = 1.0 / assembled.backend.rate_hz
    deviation = np.abs(np.diff(stamps.t) - period) * 1e3
    return deviation, np.array(gaps) * 1e3, job.cycle_time_s if job else float("nan")


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--jobs", type=int, default=3, help="rounds of (none, rrd, mcap)")
    args = parser.parse_args()
    sys.setswitchinterval(0.001)  # as serve sets it: the GIL handed over every 1 ms
    modes = ("none", "rrd", "mcap")
    rows: dict[str, dict[str, list[float]]] = {m: {} for m in modes}
    with tempfile.TemporaryDirectory() as tmp:
        for round_ in range(args.jobs):
            for mode in modes:
                dev, gaps, cycle = one_job(mode, Path(tmp))
                stats = {
                    "period_dev_p50_ms": float(np.median(dev)),
                    "period_dev_p99_ms": float(np.percentile(dev, 99)),
                    "period_dev_max_ms": float(dev.max()),
                    "beat_gap_p50_ms": float(np.median(gaps)),
                    "beat_gap_p99_ms": float(np.percentile(gaps, 99)),
                    "beat_gap_max_ms": float(gaps.max()),
                    "cycle_s": cycle,
                }
                for key, value in stats.items():
                    rows[mode].setdefault(key, []).append(value)
                print(
                    f"round {round_ + 1} {mode}: "
                    + ", ".join(f"{k} {v:.3f}" for k, v in stats.items())
                )
    keys = list(rows["none"])
    print(f"\nmedians over {args.jobs} jobs each (ratio: against no recorder)")
    print(
        f"{'':20}"
        + "".join(f"{m:>16}" for m in modes)
        + "".join(f"{m + ' ratio':>14}" for m in modes[1:])
    )
    for key in keys:
        med = {m: statistics.median(rows[m][key]) for m in modes}
        ratios = "".join(
            f"{med[m] / med['none']:>14.2f}" if med["none"] else f"{'-':>14}" for m in modes[1:]
        )
        print(f"{key:20}" + "".join(f"{med[m]:>16.3f}" for m in modes) + ratios)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
