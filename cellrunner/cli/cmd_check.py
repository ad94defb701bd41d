"""``cellrunner check CELL TASK``: prove a task feasible before anything moves."""

from __future__ import annotations

import argparse
import json
import re
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.cli.common import console, emit_json, expanded, load, parse_params, step_table
from cellrunner.model.expand import ALIGN_KEY, box_params, float_params, pattern_params
from cellrunner.model.robots import JOINT_NAMES

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress, TaskID

    from cellrunner.model.load import LoadedTask
    from cellrunner.model.params import ParamValue
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import TaskPlan
    from cellrunner.planning.world import CellWorld


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    from cellrunner.planning.cache import plan_cached
    from cellrunner.planning.world import CellWorld

    world = CellWorld(cell)
    out = None if args.json else console()  # --json is for programs: no progress bar, no rich
    use_cache = not args.no_cache
    # every slot of every pattern, every corner (and the centre) of every pose param's box,
    # the ends (and the centre) of every float param's range
    checked_params = {**pattern_params(task), **box_params(task), **float_params(task)}
    others = [
        {**params, name: slot}
        for name, slots in checked_params.items()
        for slot in slots
        if slot != params.get(name)
    ]
    n_steps = len(expanded(cell, task, params))
    with _progress(out, 1 + len(others), n_steps) as progress:
        plan = plan_cached(
            world,
            task,
            params,
            world.q_home_rad,
            use_cache=use_cache,
            on_step=progress.plan(f"{task.name} {_params_text(params)}"),
        )
        failures = _check_other_slots(world, task, params, others, use_cache, progress)
    errors = list(plan.errors) + [f"{name}={_shown(slot)}: {e}" for name, slot, e in failures]
    slots_checked = {name: list(slots) for name, slots in checked_params.items()}
    pattern = next(iter(pattern_params(task)), None)
    requested = [(pattern, params[pattern], e) for e in plan.errors] if pattern is not None else []
    grouped = group_slot_failures(
        [
            (n, s, e)
            for n, s, e in requested + failures
            if not isinstance(s, dict) and isinstance(s, int)
        ]
    )
    # pose and float params: each failing value on its own
    poses = [(name, pose, e) for name, pose, e in failures if isinstance(pose, (dict, float))]
    rows: list[dict[str, Any]] = [
        {
            "index": r.step.index,
            "name": r.step.name,
            "kind": r.step.kind,
            "duration_s": round(r.duration_s, 4),
            "status": r.status,
            "message": r.message,
            "attempts": 0,
        }
        for r in [*plan.rows, *plan.on_error]  # on_error's rows: verified from every state
    ]
    if args.save_plan and not errors:
        _save_plan(Path(args.save_plan), world, plan)
    if args.json:
        emit_json(
            {
                "ok": not errors,
                "cell": cell.cell.cell,
                "task": task.name,
                "params": params,
                "cycle_time_s": round(plan.cycle_time_s, 4),
                "steps": rows,
                "errors": errors,
                "slots_checked": slots_checked,
                "failed_slots": [
                    {"param": name, "slots": slots, "error": message}
                    for name, slots, message in grouped
                ],
                "warnings": [str(w) for w in [*cell.warnings, *task.warnings]],
            }
        )
    else:
        from rich.text import Text  # human output only: --json needs no rich

        assert out is not None  # a console unless --json

        title = f"check {task.name} on {cell.cell.cell} ({cell.cell.robot.model})" + (
            f"  params: {_params_text(params)}" if params else ""
        )
        out.print(step_table(title, [{**r, "message": _headline(r["message"])} for r in rows]))
        for name, values in slots_checked.items():
            if name.startswith(ALIGN_KEY):
                out.print(
                    f"align {name.removeprefix(ALIGN_KEY)}: {len(values)} corrections checked "
                    "(its max_correction box's centre and corners)",
                    markup=False,
                )
            elif isinstance(values[0], dict):
                out.print(
                    f"pose param {name}: {len(values)} poses checked (its box's centre and corners)",
                    markup=False,
                )
            elif isinstance(values[0], float):
                out.print(
                    f"float param {name}: {', '.join(f'{v:g}' for v in values)} checked "
                    "(its range's ends and centre)",
                    markup=False,
                )
            else:
                out.print(
                    f"pattern param {name}: {len(values)} slots checked ({values[0]}..{values[-1]})",
                    markup=False,
                )
        if pattern is None:
            for e in plan.errors:
                out.print(Text("infeasible: ", style="bold red") + Text(_lines(e)))
        for name, slots, message in grouped:
            out.print(
                Text("infeasible: ", style="bold red")
                + Text(_lines(f"{slot_range_text(name, slots)}: {message}"))
            )
        for name, pose, message in poses:
            out.print(
                Text("infeasible: ", style="bold red")
                + Text(_lines(f"{name}={_shown(pose)}: {message}"))
            )
        verdict = "[green]feasible[/]" if not errors else "[bold red]infeasible[/]"
        out.print(
            f"{verdict}: planned cycle time {plan.cycle_time_s:.2f} s "
            f"(checked in {time.perf_counter() - t0:.2f} s)"
        )
        if args.save_plan and not errors:
            out.print(f"plan saved to {args.save_plan}", markup=False)
    return 0 if not errors else 1


def _headline(message: str, width: int = 90) -> str:
    """The start of a long message for the table (the whole of it is printed below)."""
    if len(message) <= width:
        return message
    return message[:width].rsplit(" ", 1)[0] + " ... (below)"


def _lines(message: str) -> str:
    """A long diagnostic one clause per line: '; '-separated parts (each IK branch, the
    blockers, the fix) indented under the first."""
    first, *rest = message.split("; ")
    return first + "".join(f"\n    {part}" for part in rest)


def _params_text(params: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in params.items())


class _Counter:
    """What a progress bar is told: a plan starts (``plan(label)`` returns its ``on_step``),
    or plans finished elsewhere (``skip(n)``, e.g. in a forked child)."""

    def __init__(
        self,
        progress: tuple[Progress, tuple[TaskID, TaskID]] | None = None,
        steps_per_plan: int = 0,
    ) -> None:
        self._progress, self._steps_per_plan = progress, steps_per_plan
        self._started = 0

    def plan(self, label: str) -> Callable[[Step], None] | None:
        if self._progress is None:
            return None
        progress, (slots, steps) = self._progress
        if self._started:  # the plan before is over (a failed step leaves the rest unplanned)
            progress.advance(slots)
            progress.update(
                steps,
                completed=max(
                    progress.tasks[steps].completed, self._started * self._steps_per_plan
                ),
            )
        self._started += 1
        progress.update(slots, detail=label)

        def on_step(step: Step) -> None:
            progress.advance(steps)
            progress.update(steps, detail=step.label)

        return on_step

    def skip(self, n_plans: int) -> None:
        if self._progress is not None and n_plans:
            progress, (slots, steps) = self._progress
            progress.advance(slots, n_plans)
            progress.advance(steps, n_plans * self._steps_per_plan)


@contextmanager
def _progress(out: Console | None, n_plans: int, steps_per_plan: int) -> Iterator[_Counter]:
    """A progress bar over the plans (slots) and their steps on ``out`` (none when None);
    yields a :class:`_Counter`."""
    if out is None:
        yield _Counter()
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[detail]}", markup=False),
        TimeElapsedColumn(),
        console=out,
        transient=True,
    ) as progress:
        tasks = (
            progress.add_task("slots", total=n_plans, detail=""),
            progress.add_task("steps", total=n_plans * steps_per_plan, detail=""),
        )
        yield _Counter((progress, tasks), steps_per_plan)
        progress.update(tasks[0], completed=n_plans)
        progress.update(tasks[1], completed=n_plans * steps_per_plan)


def group_slot_failures(failures: list[tuple[str, int, str]]) -> list[tuple[str, list[int], str]]:
    """Per-slot errors grouped: slots whose errors differ only in numbers (joint angles,
    distances) share one entry, shown with the first slot's message.
    ``[(param, slot, error)]`` -> ``[(param, [slots], error)]`` in first-seen order."""
    groups: dict[tuple[str, str], tuple[list[int], str]] = {}
    for name, slot, message in failures:
        key = (name, _NUMBERS.sub("#", message))
        if key not in groups:
            groups[key] = ([], message)
        if slot not in groups[key][0]:
            groups[key][0].append(slot)
    return [(name, sorted(slots), message) for (name, _), (slots, message) in groups.items()]


_NUMBERS = re.compile(r"-?\d+(?:\.\d+)?")


def slot_range_text(name: str, slots: list[int]) -> str:
    """``slot``, [3, 4, 5, 9] -> 'slots 3-5, 9' (one slot: 'slot=3'; another param: 'k 3-5, 9')."""
    if len(slots) == 1:
        return f"{name}={slots[0]}"
    runs: list[list[int]] = []
    for s in sorted(slots):
        if runs and s == runs[-1][-1] + 1:
            runs[-1].append(s)
        else:
            runs.append([s])
    text = ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)
    return f"{'slots' if name == 'slot' else name} {text}"


def _check_other_slots(
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    others: list[dict[str, ParamValue]],
    use_cache: bool,
    progress: _Counter,
) -> list[tuple[str, ParamValue, str]]:
    """Every other slot of every pattern (``others``: their params); the slots to plan
    afresh are shared with a forked child when a second core is free (:func:`_plan_split`).
    Returns (param, slot, error) for each error found."""
    from cellrunner.planning.cache import cache_dir, plan_key

    cached = [
        p
        for p in others
        if use_cache
        and (cache_dir(world) / f"{plan_key(world, task, p, world.q_home_rad)}.npz").is_file()
    ]
    fresh = [p for p in others if p not in cached]
    found_all = [
        *_plan_split(world, task, fresh, use_cache, progress),
        *_slot_errors(world, task, cached, use_cache, progress),
    ]
    return [
        (k, given[k], e)
        for given, found in found_all
        for k in given
        if given[k] != params.get(k)
        for e in found
    ]


def _slot_errors(
    world: CellWorld,
    task: LoadedTask,
    slots: list[dict[str, ParamValue]],
    use_cache: bool,
    progress: _Counter | None = None,
) -> list[tuple[dict[str, ParamValue], list[str]]]:
    from cellrunner.planning.cache import plan_cached

    progress = progress or _Counter()
    return [
        (
            p,
            plan_cached(
                world,
                task,
                p,
                world.q_home_rad,
                use_cache=use_cache,
                on_step=progress.plan(_params_text(p)),
            ).errors,
        )
        for p in slots
    ]


def _plan_split(
    world: CellWorld,
    task: LoadedTask,
    slots: list[dict[str, ParamValue]],
    use_cache: bool,
    progress: _Counter,
) -> list[tuple[dict[str, ParamValue], list[str]]]:
    """``_slot_errors`` of every slot, half of them in a forked child process when this
    process may run on more than one core (planning is single-threaded Python). The
    child inherits the loaded cell; it sends back only the errors. If it fails, the
    parent plans its half too."""
    if len(slots) < 2:
        return _slot_errors(world, task, slots, use_cache, progress)
    import multiprocessing
    import os

    cores = (
        len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    )
    if cores < 2 or len(slots) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return _slot_errors(world, task, slots, use_cache, progress)
    theirs, mine = slots[: len(slots) // 2], slots[len(slots) // 2 :]
    context = multiprocessing.get_context("fork")
    reader, writer = context.Pipe(duplex=False)

    def child() -> None:
        writer.send([found for _, found in _slot_errors(world, task, theirs, use_cache)])

    process = context.Process(target=child, daemon=True)
    process.start()
    writer.close()
    results = _slot_errors(world, task, mine, use_cache, progress)
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
        return [*_slot_errors(world, task, theirs, use_cache, progress), *results]
    progress.skip(len(theirs))
    return [*zip(theirs, found, strict=True), *results]


#: how long the parent waits for the child's slots before planning them itself (s)
CHILD_TIMEOUT_S = 120.0


def _shown(value: object) -> str:
    if isinstance(value, dict):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def _save_plan(path: Path, world: CellWorld, plan: TaskPlan) -> None:
    """The approved motion as streamed: one sample per controller period, degrees."""
    c = world.loaded.cell
    steps = []
    for row in plan.rows:
        if row.trajectory is None:
            continue
        traj = row.trajectory
        samples = np.column_stack([traj.t_s, np.degrees(traj.q_rad)])
        steps.append(
            {
                "index": row.step.index,
                "name": row.step.name,
                "kind": row.step.kind,
                "samples": np.round(samples, 9).tolist(),
            }
        )
    payload = {
        "model": c.robot.model,
        "rate_hz": world.spec.rate_hz,
        "joint_names": list(JOINT_NAMES),
        "joint_range_deg": [
            list(r) for r in zip(world.spec.joint_min_deg, world.spec.joint_max_deg, strict=True)
        ],
        "mount": {"xyz": list(c.robot.mount.xyz), "rpy": list(c.robot.mount.rpy)},
        "tcp": {"xyz": list(c.tool.tcp.xyz), "rpy": list(c.tool.tcp.rpy)},
        "steps": steps,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload))
