"""``cellrunner check CELL TASK``: prove a task feasible before anything moves."""

from __future__ import annotations

import contextlib
import json
import time
from pathlib import Path

import numpy as np

from cellrunner.cli.common import console, emit_json, expanded, load, parse_params, step_table
from cellrunner.model.expand import box_params, pattern_params
from cellrunner.model.robots import JOINT_NAMES


def run(args) -> int:
    t0 = time.perf_counter()
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    from cellrunner.planning.cache import plan_cached
    from cellrunner.planning.world import CellWorld

    world = CellWorld(cell)
    out = None if args.json else console()  # --json is for programs: no spinner, no rich
    with contextlib.nullcontext() if out is None else out.status(f"planning {task.name}", spinner="dots"):
        plan = plan_cached(world, task, params, world.q_home_rad, use_cache=not args.no_cache)
        errors = list(plan.errors)
        slots_checked = _check_other_slots(world, task, params, errors, use_cache=not args.no_cache)
    rows = [{"index": r.step.index, "name": r.step.name, "kind": r.step.kind, "duration_s": round(r.duration_s, 4),
             "status": r.status, "message": r.message, "attempts": 0} for r in plan.rows]
    if args.save_plan and not errors:
        _save_plan(Path(args.save_plan), world, plan)
    if args.json:
        emit_json({"ok": not errors, "cell": cell.cell.cell, "task": task.name, "params": params,
                   "cycle_time_s": round(plan.cycle_time_s, 4), "steps": rows, "errors": errors,
                   "slots_checked": slots_checked})
    else:
        title = f"check {task.name} on {cell.cell.cell} ({cell.cell.robot.model})" + \
            (f"  params: {', '.join(f'{k}={v}' for k, v in params.items())}" if params else "")
        out.print(step_table(title, rows))
        for name, values in slots_checked.items():
            if isinstance(values[0], dict):
                out.print(f"pose param {name}: {len(values)} poses checked (its box's centre and corners)")
            else:
                out.print(f"pattern param {name}: {len(values)} slots checked ({values[0]}..{values[-1]})")
        for e in errors:
            out.print(f"[bold red]infeasible:[/] {e}")
        verdict = "[green]feasible[/]" if not errors else "[bold red]infeasible[/]"
        out.print(f"{verdict}: planned cycle time {plan.cycle_time_s:.2f} s "
                  f"(checked in {time.perf_counter() - t0:.2f} s)")
        if args.save_plan and not errors:
            out.print(f"plan saved to {args.save_plan}")
    return 0 if not errors else 1


def _check_other_slots(world, task, params, errors: list[str], use_cache: bool) -> dict[str, list]:
    """Every slot of every pattern and every corner (and the centre) of every pose param's
    box, not only the requested value; the slots to plan afresh
    are shared with a forked child when a second core is free (:func:`_plan_split`)."""
    from cellrunner.planning.cache import cache_dir, plan_key

    checked: dict[str, list] = {}
    others: list[dict] = []
    for name, slots in {**pattern_params(task), **box_params(task)}.items():
        checked[name] = list(slots)
        others += [{**params, name: slot} for slot in slots if slot != params.get(name)]
    cached = [p for p in others if use_cache
              and (cache_dir(world) / f"{plan_key(world, task, p, world.q_home_rad)}.npz").is_file()]
    fresh = [p for p in others if p not in cached]
    for given, found in [*_plan_split(world, task, fresh, use_cache), *_slot_errors(world, task, cached, use_cache)]:
        errors.extend(f"{k}={_shown(given[k])}: {e}" for k in given if given[k] != params.get(k) for e in found)
    return checked


def _slot_errors(world, task, slots: list[dict], use_cache: bool) -> list[tuple[dict, list[str]]]:
    from cellrunner.planning.cache import plan_cached
    return [(p, plan_cached(world, task, p, world.q_home_rad, use_cache=use_cache).errors) for p in slots]


def _plan_split(world, task, slots: list[dict], use_cache: bool) -> list[tuple[dict, list[str]]]:
    """``_slot_errors`` of every slot, half of them in a forked child process when this
    process may run on more than one core (planning is single-threaded Python). The
    child inherits the loaded cell; it sends back only the errors. If it fails, the
    parent plans its half too."""
    if len(slots) < 2:
        return _slot_errors(world, task, slots, use_cache)
    import multiprocessing
    import os

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores < 2 or len(slots) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return _slot_errors(world, task, slots, use_cache)
    theirs, mine = slots[: len(slots) // 2], slots[len(slots) // 2:]
    context = multiprocessing.get_context("fork")
    reader, writer = context.Pipe(duplex=False)

    def child() -> None:
        writer.send([found for _, found in _slot_errors(world, task, theirs, use_cache)])

    process = context.Process(target=child, daemon=True)
    process.start()
    writer.close()
    results = _slot_errors(world, task, mine, use_cache)
    try:
        found = reader.recv() if reader.poll(CHILD_TIMEOUT_S) else None
    except (EOFError, OSError):
        found = None
    process.join(timeout=1.0)
    if process.is_alive():
        process.kill()
        process.join()
    reader.close()
    if found is None or len(found) != len(theirs):
        return [*_slot_errors(world, task, theirs, use_cache), *results]
    return [*zip(theirs, found), *results]


#: how long the parent waits for the child's slots before planning them itself (s)
CHILD_TIMEOUT_S = 120.0


def _shown(value) -> str:
    if isinstance(value, dict):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def _save_plan(path: Path, world, plan) -> None:
    """The approved motion as streamed: one sample per controller period, degrees."""
    c = world.loaded.cell
    steps = []
    for row in plan.rows:
        if row.trajectory is None:
            continue
        traj = row.trajectory
        samples = np.column_stack([traj.t_s, np.degrees(traj.q_rad)])
        steps.append({"index": row.step.index, "name": row.step.name, "kind": row.step.kind,
                      "samples": np.round(samples, 9).tolist()})
    payload = {"model": c.robot.model, "rate_hz": world.spec.rate_hz,
               "joint_names": list(JOINT_NAMES),
               "mount": {"xyz": list(c.robot.mount.xyz), "rpy": list(c.robot.mount.rpy)},
               "tcp": {"xyz": list(c.tool.tcp.xyz), "rpy": list(c.tool.tcp.rpy)},
               "steps": steps}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload))
