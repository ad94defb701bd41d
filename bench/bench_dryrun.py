"""Dry-run speed and fidelity (issue 4).

For each case, the job runs through the real cell controller against the MuJoCo twin;
we time only the control loop (model build and planning excluded) and compare with the
peer: streaming the same approved trajectories straight into the same twin with no engine
(``servo`` + ``wait_period``), and the bare physics: ``mujoco.mj_step`` on the same
compiled model and data, as many steps as the job's simulated time needs, nothing else
(``raw mj_step``). Prints medians over runs and the ratios.

    python bench/bench_dryrun.py [--runs 5]

Targets: real-time factor >= 0.8x the raw mj_step rate; |simulated - planned| cycle time < 2 %.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cellrunner.backends.sim.backend import SimBackend  # noqa: E402
from cellrunner.execution.cell import CellController  # noqa: E402
from cellrunner.execution.journal import Journal  # noqa: E402
from cellrunner.execution.loop import ControlLoop  # noqa: E402
from cellrunner.execution.planner import job_planner  # noqa: E402
from cellrunner.model.load import load_cell, load_task  # noqa: E402
from cellrunner.planning.world import CellWorld  # noqa: E402
from cellrunner.sim.from_cell import description_of  # noqa: E402

CASES = [
    ("demo UR5e pick/place slot 0", "cells/demo_ur5e.yaml", "tasks/pick_place.yaml", {"slot": 0}),
    ("demo UR5e pick/place slot 11", "cells/demo_ur5e.yaml", "tasks/pick_place.yaml", {"slot": 11}),
]


def engine_run(cell, task, params) -> tuple[float, float, float, float]:
    """(simulated s, wall s of the loop, planned cycle s, simulated cycle s)."""
    world = CellWorld(cell)
    backend = SimBackend(description_of(cell))
    controller = CellController(
        cell, {1: task}, backend, Journal(":memory:"), job_planner(world), wait_for_unhold=False
    )
    controller.setup()
    loop = ControlLoop(controller)
    loop.step(3)
    controller.start_job(1, params, "bench", "cli")
    loop.step(1)  # planning starts on the control thread
    controller.wait_for_plan(timeout_s=600.0)  # planning excluded from the timing
    sim0, wall0 = backend.read_state().time_s, time.perf_counter()
    loop.run_job(max_s=3600.0)
    planned = controller.last_job.planned_cycle_time_s
    wall = time.perf_counter() - wall0
    sim = backend.read_state().time_s - sim0
    result = controller.status().last_result
    assert result.result_code == 0, result
    controller.close()
    return sim, wall, planned, result.cycle_time_s


def raw_stream(cell, task, params) -> tuple[float, float]:
    """The peer: the same trajectories streamed with no engine at all."""
    from cellrunner.planning.cache import plan_cached

    world = CellWorld(cell)
    plan = plan_cached(world, task, params, world.q_home_rad)
    backend = SimBackend(description_of(cell))
    backend.connect()
    trajectories = [plan.nominal(s) for s in plan.steps if s.is_motion]
    sim0, wall0 = backend.read_state().time_s, time.perf_counter()
    for approved in trajectories:
        for i in range(len(approved.trajectory.q_rad)):
            backend.servo(approved, i)
            backend.wait_period()
            backend.read_state()
    return backend.read_state().time_s - sim0, time.perf_counter() - wall0


def raw_mj_step(cell, sim_s: float) -> float:
    """Real-time factor of mujoco.mj_step alone on the twin's own compiled model (the
    arm at rest at home), for ``sim_s`` of simulated time."""
    import mujoco

    backend = SimBackend(description_of(cell))
    backend.connect()
    world = backend.world
    model, data = world.model, world.data
    steps = int(sim_s / model.opt.timestep)
    wall0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    wall = time.perf_counter() - wall0
    backend.close()
    return steps * model.opt.timestep / wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    print(
        f"{'case':32s} {'engine RTF':>11s} {'stream RTF':>10s} {'mj_step RTF':>11s} {'engine/mj_step':>14s} "
        f"{'planned s':>10s} {'simulated s':>12s} {'diff %':>7s}"
    )
    worst_rtf, worst_diff = float("inf"), 0.0
    for name, cell_path, task_path, params in CASES:
        cell = load_cell(ROOT / cell_path)
        task = load_task(ROOT / task_path, cell)
        engine, raw, diffs, physics = [], [], [], []
        planned = simulated = 0.0
        for _ in range(args.runs):
            sim, wall, planned, simulated = engine_run(cell, task, params)
            engine.append(sim / wall)
            diffs.append(abs(simulated - planned) / planned * 100)
            sim_r, wall_r = raw_stream(cell, task, params)
            raw.append(sim_r / wall_r)
            physics.append(raw_mj_step(cell, sim))
        e, r, d = statistics.median(engine), statistics.median(raw), statistics.median(diffs)
        p = statistics.median(physics)
        worst_rtf, worst_diff = min(worst_rtf, e / p), max(worst_diff, d)
        print(
            f"{name:32s} {e:10.1f}x {r:9.1f}x {p:10.1f}x {e / p:13.2f}x {planned:10.2f} {simulated:12.2f} {d:7.2f}"
        )
    print(
        f"\nmedians of {args.runs} runs; targets: engine >= 0.8x raw mj_step (worst {worst_rtf:.2f}x: "
        f"{'met' if worst_rtf >= 0.8 else 'missed'}), cycle difference < 2 % (worst {worst_diff:.2f} %: "
        f"{'met' if worst_diff < 2 else 'missed'})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
