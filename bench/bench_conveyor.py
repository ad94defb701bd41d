"""How closely the arm follows a part on the twin's moving belt while it grips it.

Run: ``python bench/bench_conveyor.py [--speeds 0.15 0.25 0.30] [--parts 20]`` from the
repository root.

For each belt speed, one job of the reference task (``cells/conveyor_pick_ur10e.yaml``,
``tasks/conveyor_pick.yaml``) is rehearsed on the MuJoCo twin with the belt running at that
speed. Every period where the TCP is down at the part (within ``DOWN_M`` of the part's
centre in height, the part still resting on the belt: the descent's end, the grip's
dwell and the jaws closing, until the lift raises it) the tracking error is taken as the TCP's distance from the part's centre seen
from above, both measured in the physics (the TCP against the part, not the set-point
against itself: the grip frame is the part's centre). Printed: the job's result, the
samples, the error's median, p99 and maximum (mm), and the p99 against the 1 mm target.

Then the line (``--parts N``, 0 skips it): the reference cell's belt at ``speed_max`` with its
feed (``sim: feed``: a block every ``every`` s, jittered), jobs one after another until N
have ended, the feed driven by the twin's time. Printed: the parts fed, picked (jobs that
ended 0), let go (jobs that ended 109), gone by (blocks downstream of the window on the
belt, never picked), the picks per minute of the twin's time against the cell's own bound
(``check``'s parts/min at speed_max), and the wall time.

Then what a line does to the belt under a pick (``bench/conveyor_faults.py``): a drive's
ramp down, a stand and a ramp up (the arm holds with it: 0), a stop at once and an encoder
jump (controlled stops: 100), each in its own job, every run.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
CELL = REPO / "cells" / "conveyor_pick_ur10e.yaml"
TASK = REPO / "tasks" / "conveyor_pick.yaml"
#: a period counts when the TCP is within this of the part's centre in height, m
DOWN_M = 0.005
#: the part rests on the twin's belt with its centre this high, m; it counts as on the belt
#: (not lifted yet) within ON_BELT_M of it
RESTING_Z_M = 0.827
ON_BELT_M = 0.002
#: the belt's path runs along world Y at this X, m (the part is on it, not in the tray)
BELT_X_M = 0.75
#: the target on the p99 tracking error while gripping, m
TARGET_M = 0.001


class Sampler:
    """The TCP's distance from the part seen from above, every period it is down at it."""

    def __init__(self, part: str) -> None:
        self.part = part
        self.errors_m: list[float] = []

    def __call__(self, cell: Any) -> None:
        world = cell.backend.world
        if world is None:
            return
        tcp = world.tcp_pose_world()[:3, 3]
        part = world.part_pose_world(self.part)[:3, 3]
        on_belt = (
            abs(float(part[2]) - RESTING_Z_M) <= ON_BELT_M
            and abs(float(part[0]) - BELT_X_M) <= ON_BELT_M
        )
        if on_belt and abs(float(tcp[2] - part[2])) <= DOWN_M:
            self.errors_m.append(float(np.linalg.norm(tcp[:2] - part[:2])))


def measure(speed_mps: float) -> dict[str, Any]:
    from bench.conveyor_faults import rehearse_one

    sampler = Sampler("block")
    job, wall_s = rehearse_one(CELL, TASK, sampler, belt_mps=speed_mps)
    e = np.asarray(sampler.errors_m) * 1000
    return {
        "speed": speed_mps,
        "result": int(job.code),
        "samples": len(e),
        "p50": float(np.median(e)) if len(e) else float("nan"),
        "p99": float(np.percentile(e, 99)) if len(e) else float("nan"),
        "max": float(e.max()) if len(e) else float("nan"),
        "wall_s": wall_s,
    }


def bound_parts_per_minute() -> float:
    """``check``'s parts/min at speed_max for the reference task (its tracking proof)."""
    from cellrunner.model.expand import expand, resolve_params
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.task_plan import plan_task
    from cellrunner.planning.tracking import prove_tracking
    from cellrunner.planning.world import CellWorld

    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    world = CellWorld(cell)
    plan = plan_task(
        world, expand(task, cell.cell, resolve_params(task.task, {})), world.q_home_rad
    )
    (proof,) = prove_tracking(world, plan)
    return float(proof.parts_per_minute)


def _take_away_placed(world: Any, feeder: Any) -> None:
    """The line takes the placed block out of the tray (the task has one slot): parked far
    out, where the feed takes its spare copies from."""
    from cellrunner.sim.feed import PARK_X_M

    for name in ("block", *feeder.fed):
        xyz = world.part_pose_world(name)[:3, 3]
        if abs(float(xyz[0]) - BELT_X_M) > 0.2 and abs(float(xyz[0])) < PARK_X_M / 2:
            T = np.eye(4)
            T[:3, 3] = (PARK_X_M, -5.0 - len(feeder.fed), 0.03)
            feeder._put(name, T)


#: the top of the reference cell's belt, world z (m): a block rides on it, centre 25 mm up
BELT_TOP_Z_M = 0.80
#: copies of the block the line's twin keeps (see run_line)
LINE_COPIES = 24


class _GoneBy:
    """Counts the blocks that ride past the window's end on the belt (unpicked), each
    once, as they go (a copy is fed again later): looked at every 50 periods (0.1 s; a
    block takes 1.7 s from the window's end to the belt's at 0.3 m/s)."""

    def __init__(self, world: Any, feeder: Any, window_end_y: float) -> None:
        self.world, self.feeder, self.window_end_y = world, feeder, window_end_y
        self.count, self._ticks = 0, 0
        self._past: set[tuple[str, int]] = set()

    def __call__(self, _cell: Any) -> None:
        self._ticks += 1
        if _cell is not None and self._ticks % 50:
            return
        held = self.world.gripped
        for name in {"block", *self.feeder.fed} - set(held):
            xyz = self.world.part_pose_world(name)[:3, 3]
            on_belt = abs(float(xyz[0]) - BELT_X_M) < 0.2 and float(xyz[2]) < BELT_TOP_Z_M + 0.06
            if on_belt and float(xyz[1]) > self.window_end_y:
                fed_at = [t for n, t in self.feeder.timed if n == name]
                key = (name, fed_at[-1] if fed_at else -1.0)  # this copy, this time it was fed
                if key not in self._past:
                    self._past.add(key)
                    self.count += 1


def feeder_count(feeder: Any) -> int:
    """The blocks fed so far: the cell's own block and every one fed by time."""
    return 1 + len(feeder.timed)


def run_line(jobs: int) -> dict[str, Any]:
    """``jobs`` jobs of the reference task in a row on the twin's belt at speed_max, the
    cell's feed coming by the twin's time (see the module docstring)."""
    from cellrunner.backends.factory import make_backend
    from cellrunner.cli.common import console
    from cellrunner.execution.rehearsal import start_rehearsal
    from cellrunner.model.job_steps import job_steps
    from cellrunner.model.load import load_cell, load_task

    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    conveyor = cell.cell.conveyors["belt"]
    # the twin keeps this many copies of the block (a MuJoCo model cannot grow): the line
    # takes each placed block away and the feed uses the oldest again once all are out.
    # One copy a job made the physics of a long run slow down with every job (500 parked
    # free bodies integrated every step)
    copies = min(jobs, LINE_COPIES)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=[{}] * copies)
    rehearsal = start_rehearsal(cell, task, backend, console())
    codes: list[int] = []
    try:
        world = backend.world
        feeder = world.feeder
        assert feeder is not None and feeder.desc.every_s is not None, "the cell feeds by time"
        rehearsal.loop.add_observer(lambda _cell: feeder.update())
        gone = _GoneBy(world, feeder, float(conveyor.window[1]))
        rehearsal.loop.add_observer(gone)
        steps = job_steps(task, cell.cell, {})
        t0, w0 = world.time_s, time.perf_counter()
        for _ in range(jobs):
            job = rehearsal.rehearse({}, steps)
            codes.append(int(job.code))
            print(
                f"job {len(codes)}: {int(job.code)} at {world.time_s - t0:.0f} s "
                f"({time.perf_counter() - w0:.0f} s wall)",
                file=sys.stderr,
            )
            if job.code != 0:
                print(f"job {len(codes)}: {job.payload['result_text']}", file=sys.stderr)
                break  # the cell stopped: the line run ends there
            _take_away_placed(world, feeder)
        elapsed_s, wall_s = world.time_s - t0, time.perf_counter() - w0
        gone(None)
        gone_by = gone.count
        fed = feeder_count(feeder)
    finally:
        rehearsal.close()
    picked = codes.count(0)
    return {
        "jobs": jobs,
        "fed": fed,
        "picked": picked,
        "let_go": codes.count(109),
        "other": len(codes) - picked - codes.count(109),
        "gone_by": gone_by,
        "codes": codes,
        "ppm": 60.0 * picked / elapsed_s if elapsed_s > 0 else float("nan"),
        "sim_s": elapsed_s,
        "wall_s": wall_s,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", type=float, nargs="+", default=[0.15, 0.25, 0.30])
    parser.add_argument("--parts", type=int, default=20, help="jobs of the line run (0: none)")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO))
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    if args.parts > 0:
        line = run_line(args.parts)
        bound = bound_parts_per_minute()
        print(
            "| jobs | fed | picked | let go (109) | other | gone by | picks/min | bound | ratio | twin s | wall s |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        print(
            f"| {line['jobs']} | {line['fed']} | {line['picked']} | {line['let_go']} | "
            f"{line['other']} | {line['gone_by']} | {line['ppm']:.2f} | {bound:.2f} | "
            f"{line['ppm'] / bound:.2f} | {line['sim_s']:.0f} | {line['wall_s']:.0f} |"
        )
        print(f"job results: {line['codes']}\n")
    from bench.conveyor_faults import EXPECTED, run_fault

    faults = [run_fault(kind, CELL, TASK) for kind in EXPECTED]
    print(
        "| the line does | result | expected | spread while standing mm | arm's speed then rad/s | wall s |"
    )
    print("|---|---|---|---|---|---|")
    for f in faults:
        print(
            f"| {f['kind']} | {f['result']} | {EXPECTED[f['kind']]} | "
            + ("-" if np.isnan(f["spread_mm"]) else f"{f['spread_mm']:.2f}")
            + " | "
            + ("-" if np.isnan(f["still_rad_s"]) else f"{f['still_rad_s']:.4f}")
            + f" | {f['wall_s']:.1f} |"
        )
        if f["result"] != 0:
            print(f"  {f['kind']}: {f['text']}")
    print()
    rows = [measure(v) for v in args.speeds]
    print("| belt m/s | result | samples | p50 mm | p99 mm | max mm | p99/target | wall s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['speed']:.2f} | {r['result']} | {r['samples']} | {r['p50']:.3f} | "
            f"{r['p99']:.3f} | {r['max']:.3f} | {r['p99'] / (TARGET_M * 1000):.2f} | "
            f"{r['wall_s']:.1f} |"
        )
    handled = all(f["acted"] and f["result"] == EXPECTED[f["kind"]] for f in faults)
    return 0 if handled and all(r["result"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
