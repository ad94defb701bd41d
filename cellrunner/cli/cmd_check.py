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

from cellrunner.cli.common import console, emit_json, load, parse_params, step_table
from cellrunner.model.expand import ALIGN_KEY, pattern_params
from cellrunner.model.robots import JOINT_NAMES

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress, TaskID

    from cellrunner.model.step import Step
    from cellrunner.planning.job_plan import JobPlan
    from cellrunner.planning.tracking import TrackingProof
    from cellrunner.planning.world import CellWorld


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    from cellrunner.execution.slot_sweep import other_values, sweep
    from cellrunner.planning.world import CellWorld

    world = CellWorld(cell)
    watched = getattr(args, "watch", None)
    if watched:
        world = world.with_obstacles(*_snapshot_obstacles(watched, cell))
    out = None if args.json else console()  # --json is for programs: no progress bar, no rich
    with _progress(out, 1 + len(other_values(task, params))) as progress:
        swept = sweep(
            world, task, params, use_cache=not (args.no_cache or watched), progress=progress
        )
    plan = swept.plan
    failures = [(f.param, f.value, f.error) for f in swept.failures]
    errors = list(plan.errors) + [f"{name}={_shown(slot)}: {e}" for name, slot, e in failures]
    tracking = _prove_tracking(world, plan)
    errors += [p.error for p in tracking if p.error is not None]
    slots_checked = swept.checked
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
    poses = [(name, pose, e) for name, pose, e in failures if isinstance(pose, (dict, float, str))]
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
        for r in plan.rows  # on_error's rows last: verified from every state
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
                "conveyors": [p.to_json() for p in tracking],
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
            elif isinstance(values[0], str):
                out.print(
                    f"frame param {name}: {', '.join(str(v) for v in values)} checked (every choice)",
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
        for proof in tracking:
            out.print(_lines(proof.summary()), markup=False)
            if proof.error is not None:
                out.print(Text("infeasible: ", style="bold red") + Text(_lines(proof.error)))
        verdict = "[green]feasible[/]" if not errors else "[bold red]infeasible[/]"
        out.print(
            f"{verdict}: planned cycle time {plan.cycle_time_s:.2f} s "
            f"(checked in {time.perf_counter() - t0:.2f} s)"
        )
        if args.save_plan and not errors:
            out.print(f"plan saved to {args.save_plan}", markup=False)
    return 0 if not errors else 1


def _prove_tracking(world: CellWorld, plan: JobPlan) -> list[TrackingProof]:
    """The proof of the task's tracked steps on its conveyors (none without a track)."""
    if not any(step.kind == "track" for step in plan.steps):
        return []
    from cellrunner.planning.tracking import prove_tracking

    return prove_tracking(world, plan.task_plan)


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
        self, progress: tuple[Progress, tuple[TaskID, TaskID]] | None = None, n_plans: int = 0
    ) -> None:
        self._progress, self._n_plans = progress, n_plans
        self._steps_per_plan = 0  # known once the first plan has expanded its steps
        self._started = 0

    def sized(self, steps_per_plan: int) -> None:
        """Each plan has ``steps_per_plan`` steps (told after the first is planned)."""
        self._steps_per_plan = steps_per_plan
        if self._progress is not None:
            progress, (_, steps) = self._progress
            progress.update(steps, total=self._n_plans * steps_per_plan)

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
def _progress(out: Console | None, n_plans: int) -> Iterator[_Counter]:
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
            progress.add_task("steps", total=None, detail=""),
        )
        counter = _Counter((progress, tasks), n_plans)
        yield counter
        progress.update(tasks[0], completed=n_plans)
        progress.update(tasks[1], completed=n_plans * counter._steps_per_plan)


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


def _shown(value: object) -> str:
    if isinstance(value, dict):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def _save_plan(path: Path, world: CellWorld, plan: JobPlan) -> None:
    """The approved motion as streamed: one sample per controller period, degrees."""
    c = world.loaded.cell
    steps = []
    for row in plan.task_plan.rows:
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


def _snapshot_obstacles(path: str, cell: Any) -> list[Any]:
    """The occupied voxels of a saved map, grown by the cell's padding, as one obstacle
    (none when the map is empty); a file that is no map is a usage error (exit 2)."""
    import numpy as np

    from cellrunner.errors import UsageError
    from cellrunner.model.geometry import Placed, Voxels
    from cellrunner.perception.occupancy import OccupancyMap

    try:
        snapshot = OccupancyMap.load(path)
    except ValueError as exc:
        raise UsageError(f"--watch {exc}") from None
    centres = snapshot.occupied_centres()
    if not len(centres):
        return []
    padding = cell.cell.watch.padding if cell.cell.watch is not None else 0.03
    return [Placed("watched zone", Voxels(centres, snapshot.voxel_m, padding), np.eye(4))]
