"""Dry-run speed and fidelity (issue 4, issue 11).

For each case, the job runs through the real cell controller against the MuJoCo twin;
we time only the control loop (model build and planning excluded), as ``dry-run`` runs
it (with look-ahead: streamed motions advance many periods per call, their physics in
``mujoco.rollout``) and one period at a time (``dry-run --per-period``, the loop before
look-ahead), and compare with two peers on the same compiled model:

- ``stream``: the same approved trajectories streamed straight into the twin with no
  engine (``servo`` + ``wait_period``);
- ``raw mj_step``: the bare physics of the same job: ``mujoco.mj_step`` from the job's
  starting state, fed the very actuator inputs the twin applied step by step (recorded in
  an untimed run), nothing else. (Stepping the arm at rest instead, as this bench once
  did, is ~1.7x cheaper per step than stepping the job's motion and contacts: measured.)

Real-time factors are simulated time over CPU time of this process (``time.process_time``;
everything is single-threaded here, and on a shared machine wall time mostly measures the
other processes); wall-clock factors are printed too. A breakdown of the engine's CPU time
per control period (physics, the twin's own Python per period, state reads, the engine's
tick) comes from one more run with timers around those calls; a second breakdown shows
where the look-ahead run's time goes (rollouts, the periods still stepped one by one,
replanning, tracking samples). Medians over runs.

    python bench/bench_dryrun.py [--runs 5]

Targets: real-time factor >= 0.8x the raw mj_step rate; |simulated - planned| cycle time < 2 %.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cellrunner.backends.sim.backend import SimBackend  # noqa: E402
from cellrunner.execution.assembly import assemble_cell  # noqa: E402
from cellrunner.execution.journal import Journal  # noqa: E402
from cellrunner.model.load import load_cell, load_task  # noqa: E402
from cellrunner.planning.world import CellWorld  # noqa: E402
from cellrunner.sim.from_cell import description_of  # noqa: E402

CASES = [
    ("demo UR5e pick/place slot 0", "cells/demo_ur5e.yaml", "tasks/pick_place.yaml", {"slot": 0}),
    ("demo UR5e pick/place slot 11", "cells/demo_ur5e.yaml", "tasks/pick_place.yaml", {"slot": 11}),
]


def _started(cell, task, params, lookahead=True):
    """A controller with the job planned and about to move: (controller, loop, backend)."""
    assembled = assemble_cell(
        cell, {1: task}, "sim", journal=Journal(":memory:"), lookahead=lookahead
    ).setup()
    controller, loop, backend = assembled.controller, assembled.loop, assembled.backend
    loop.step(3)
    controller.start_job(1, params, "bench", "cli")
    loop.step(1)  # planning starts on the control thread
    controller.wait_for_plan(timeout_s=600.0)  # planning excluded from the timing
    return controller, loop, backend


def engine_run(cell, task, params, lookahead=True) -> tuple[float, float, float, float, float]:
    """(simulated s, CPU s of the loop, wall s of the loop, planned cycle s, simulated
    cycle s)."""
    controller, loop, backend = _started(cell, task, params, lookahead)
    sim0, cpu0, wall0 = backend.read_state().time_s, time.process_time(), time.perf_counter()
    loop.run_job(max_s=3600.0)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    planned = controller.last_job.planned_cycle_time_s
    sim = backend.read_state().time_s - sim0
    result = controller.status().last_result
    assert result.result_code == 0, result
    controller.close()
    return sim, cpu, wall, planned, result.cycle_time_s


class _Timed:
    """Stands in for an object, timing (CPU) the calls of the named methods into ``spent``."""

    def __init__(self, target, names, spent: Counter, counts: Counter, on_call=None):
        self._target, self._names, self._spent, self._counts = target, names, spent, counts
        self._on_call = on_call

    def __getattr__(self, name):
        attr = getattr(self._target, name)
        if name not in self._names:
            return attr
        spent, counts, on_call, clock = self._spent, self._counts, self._on_call, time.process_time

        def timed(*args, **kwargs):
            if on_call is not None:
                on_call(name, args)
            t = clock()
            try:
                return attr(*args, **kwargs)
            finally:
                spent[name] += clock() - t
                counts[name] += 1

        return timed


def recorded_run(cell, task, params):
    """One untimed engine run with timers: (the physics state where the loop starts, the
    actuator inputs before each mj_step, CPU s per control period by part, periods)."""
    import mujoco

    controller, loop, backend = _started(cell, task, params, lookahead=False)
    world = backend.world
    state = np.empty(mujoco.mj_stateSize(world.model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(world.model, world.data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    spent, counts, inputs = Counter(), Counter(), []

    def record(name, args):
        inputs.append(args[1].ctrl.copy())

    world._mj = _Timed(world._mj, {"mj_step"}, spent, counts, record)
    step_period = world.step_period

    def timed_period():
        t = time.process_time()
        step_period()
        spent["twin step"] += time.process_time() - t

    world.step_period = timed_period
    read_state = backend.read_state

    def timed_read():
        t = time.process_time()
        try:
            return read_state()
        finally:
            spent["state reads"] += time.process_time() - t

    backend.read_state = timed_read
    tick = controller.tick

    def timed_tick():
        t = time.process_time()
        try:
            return tick()
        finally:
            spent["engine tick"] += time.process_time() - t

    controller.tick = timed_tick
    cpu0 = time.process_time()
    loop.run_job(max_s=3600.0)
    spent["loop"] = time.process_time() - cpu0
    periods = loop.ticks
    controller.close()
    return state, np.array(inputs), spent, periods


def lookahead_breakdown(cell, task, params) -> tuple[Counter, Counter, int, int]:
    """One look-ahead run with timers: (CPU s by part, calls by part, periods, periods
    looked ahead). Parts: rollouts (the physics of the periods looked ahead, and of those
    rolled out beyond a cut), the periods stepped one at a time, replanning (inside those
    periods), tracking samples, holds (steps that wait with the arm still: grip, weigh,
    release; their periods counted), and the rest of the look-ahead's Python."""
    import cellrunner.execution.lookahead as engine_ahead
    import cellrunner.sim.lookahead as twin_ahead

    controller, loop, _ = _started(cell, task, params)
    loop.step(1)  # the runner starts
    runner = controller.last_runner or controller._job.runner
    spent, counts = Counter(), Counter()
    undo = []

    def timed(owner, name, key):
        f = getattr(owner, name)

        def wrapper(*args, **kwargs):
            t = time.process_time()
            try:
                result = f(*args, **kwargs)
                if key == "holds":  # periods of steps holding the arm still, looked ahead
                    counts["held periods"] += result
                return result
            finally:
                spent[key] += time.process_time() - t
                counts[key] += 1

        setattr(owner, name, wrapper)
        undo.append((owner, name, f))

    timed(twin_ahead.Lookahead, "preview", "rollouts (preview)")
    timed(twin_ahead.Lookahead, "commit", "commits")
    timed(engine_ahead, "_track", "tracking samples")
    timed(engine_ahead, "_hold", "holds")
    timed(controller, "fast_forward", "look-ahead calls (all)")
    timed(loop, "step", "periods one at a time (all)")
    timed(runner.ctx.motions, "replan", "replanning")
    cpu0 = time.process_time()
    try:
        loop.run_job(max_s=3600.0)
    finally:
        for owner, name, f in undo:
            setattr(owner, name, f)
    spent["loop"] = time.process_time() - cpu0
    periods, ahead = loop.ticks, loop.ticks_ahead
    controller.close()
    return spent, counts, periods, ahead


def raw_mj_step(cell, state: np.ndarray, inputs: np.ndarray) -> tuple[float, float, float]:
    """The bare physics of the job: from ``state``, ``mj_step`` fed ``inputs`` (one row
    per step) on the twin's own compiled model: (simulated s, CPU s, wall s)."""
    import mujoco

    backend = SimBackend(description_of(cell))
    backend.connect()
    world = backend.world
    model, data = world.model, world.data
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    ctrl, step = data.ctrl, mujoco.mj_step
    cpu0, wall0 = time.process_time(), time.perf_counter()
    for row in inputs:
        ctrl[:] = row
        step(model, data)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    backend.close()
    return len(inputs) * model.opt.timestep, cpu, wall


def raw_stream(cell, task, params) -> tuple[float, float]:
    """The peer: the same trajectories streamed with no engine at all: (simulated s, CPU s)."""
    from cellrunner.planning.job_plan import plan_job

    world = CellWorld(cell)
    plan = plan_job(world, task, params, world.q_home_rad).task_plan
    backend = SimBackend(description_of(cell))
    backend.connect()
    trajectories = [plan.nominal(s) for s in plan.steps if s.is_motion]
    sim0, cpu0 = backend.read_state().time_s, time.process_time()
    for approved in trajectories:
        for i in range(len(approved.trajectory.q_rad)):
            backend.servo(approved, i)
            backend.wait_period()
            backend.read_state()
    return backend.read_state().time_s - sim0, time.process_time() - cpu0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args()
    report = []
    print(
        f"{'case':30s} {'engine RTF':>10s} {'stream RTF':>10s} {'mj_step RTF':>11s} "
        f"{'engine/mj_step':>14s} {'(wall)':>7s} {'per-period':>10s} {'planned s':>9s} "
        f"{'simulated s':>11s} {'diff %':>6s}"
    )
    worst_rtf, worst_diff, breakdowns, ahead_breakdowns = float("inf"), 0.0, [], []
    for name, cell_path, task_path, params in CASES:
        cell = load_cell(ROOT / cell_path)
        task = load_task(ROOT / task_path, cell)
        engine_run(cell, task, params)  # warm-up: first-use imports and caches
        state, inputs, spent, periods = recorded_run(cell, task, params)
        breakdowns.append((name, spent, periods))
        ahead_breakdowns.append((name, *lookahead_breakdown(cell, task, params)))
        engine, engine_wall, raw, diffs, physics, physics_wall = [], [], [], [], [], []
        per_period = []
        planned = simulated = 0.0
        for _ in range(args.runs):  # interleaved: engine, per-period, stream, bare physics
            sim, cpu, wall, planned, simulated = engine_run(cell, task, params)
            engine.append(sim / cpu)
            engine_wall.append(sim / wall)
            sim_1, cpu_1, *_ = engine_run(cell, task, params, lookahead=False)
            per_period.append(sim_1 / cpu_1)
            diffs.append(abs(simulated - planned) / planned * 100)
            sim_r, cpu_r = raw_stream(cell, task, params)
            raw.append(sim_r / cpu_r)
            sim_p, cpu_p, wall_p = raw_mj_step(cell, state, inputs)
            physics.append(sim_p / cpu_p)
            physics_wall.append(sim_p / wall_p)
        e, r, d = statistics.median(engine), statistics.median(raw), statistics.median(diffs)
        p = statistics.median(physics)
        ew, pw = statistics.median(engine_wall), statistics.median(physics_wall)
        e1 = statistics.median(per_period)
        worst_rtf, worst_diff = min(worst_rtf, e / p), max(worst_diff, d)
        report.append(
            {
                "case": name,
                "engine_rtf": e,
                "stream_rtf": r,
                "mj_step_rtf": p,
                "ratio": e / p,
                "ratio_wall": ew / pw,
                "per_period_rtf": e1,
                "per_period_ratio": e1 / p,
                "cycle_diff_pct": d,
            }
        )
        print(
            f"{name:30s} {e:9.1f}x {r:9.1f}x {p:10.1f}x {e / p:13.2f}x {ew / pw:6.2f}x "
            f"{e1 / p:9.2f}x {planned:9.2f} {simulated:11.2f} {d:6.2f}"
        )
    print(
        f"\nmedians of {args.runs} runs, real-time factors in CPU time ((wall): the same ratio "
        f"by the wall clock; per-period: the loop one period at a time, dry-run --per-period, "
        f"against the same raw mj_step); targets: engine >= 0.8x raw mj_step (worst {worst_rtf:.2f}x: "
        f"{'met' if worst_rtf >= 0.8 else 'missed'}), cycle difference < 2 % (worst "
        f"{worst_diff:.2f} %: {'met' if worst_diff < 2 else 'missed'})"
    )
    print("\nwhere the look-ahead run's CPU time goes (ms per job, one timed run):")
    for name, spent, counts, periods, ahead in ahead_breakdowns:
        one_by_one = spent["periods one at a time (all)"]
        replans = spent["replanning"]
        rest = spent["loop"] - spent["look-ahead calls (all)"] - one_by_one
        calls = spent["look-ahead calls (all)"] - spent["rollouts (preview)"]
        print(
            f"  {name}: {spent['loop'] * 1e3:.1f} in all, {periods} periods, {ahead} of them "
            f"({ahead / periods:.0%}) in {counts['commits']} look-aheads ({counts['held periods']} "
            f"periods holding the arm still) = rollouts "
            f"{spent['rollouts (preview)'] * 1e3:.1f} ({counts['rollouts (preview)']} calls) + "
            f"look-ahead Python {calls * 1e3:.1f} (tracking samples "
            f"{spent['tracking samples'] * 1e3:.1f}) + {periods - ahead} periods one at a time "
            f"{one_by_one * 1e3:.1f} (of which replanning {replans * 1e3:.1f} in "
            f"{counts['replanning']} replans) + loop {rest * 1e3:.1f}"
        )
    print("\nwhere a control period's CPU time goes, one period at a time (us per period):")
    for name, spent, periods in breakdowns:
        us = {k: v / periods * 1e6 for k, v in spent.items()}
        twin_python = us["twin step"] - us["mj_step"]
        rest = us["loop"] - us["twin step"] - us["engine tick"] - us["state reads"]
        print(
            f"  {name}: {us['loop']:.0f} in all = physics (mj_step) {us['mj_step']:.0f} + twin "
            f"Python around it {twin_python:.0f} + engine tick {us['engine tick']:.0f} + "
            f"state reads {us['state reads']:.0f} + loop and observers {rest:.0f}"
        )
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "runs": args.runs,
                    "cases": report,
                    "worst_ratio": worst_rtf,
                    "worst_cycle_diff_pct": worst_diff,
                },
                indent=2,
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
