"""``cellrunner check CELL TASK``: prove a task feasible before anything moves."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.cli.common import console, emit_json, load, parse_params, step_table
from cellrunner.model.robots import JOINT_NAMES

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress, TaskID

    from cellrunner.execution.check_report import CheckReport
    from cellrunner.model.step import Step
    from cellrunner.planning.job_plan import JobPlan
    from cellrunner.planning.tracking import TrackingProof
    from cellrunner.planning.world import CellWorld


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    from cellrunner.execution.check_report import check_report
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
    report = check_report(swept, task, params, _prove_tracking(world, swept.plan))
    if args.save_plan and report.ok:
        _save_plan(Path(args.save_plan), world, report.plan)
    warnings = [str(w) for w in [*cell.warnings, *task.warnings]] + report.plan.warnings
    if args.json:
        emit_json(_payload(report, cell.cell.cell, task.name, warnings))
        return 0 if report.ok else 1
    assert out is not None  # a console unless --json
    title = f"check {task.name} on {cell.cell.cell} ({cell.cell.robot.model})" + (
        f"  params: {_params_text(params)}" if params else ""
    )
    _print(out, title, report)
    for warning in report.plan.warnings:
        out.print(f"warning: {warning}", markup=False, style="yellow")
    verdict = "[green]feasible[/]" if report.ok else "[bold red]infeasible[/]"
    out.print(
        f"{verdict}: planned cycle time {report.plan.cycle_time_s:.2f} s "
        f"(checked in {time.perf_counter() - t0:.2f} s)"
    )
    if args.save_plan and report.ok:
        out.print(f"plan saved to {args.save_plan}", markup=False)
    return 0 if report.ok else 1


def _payload(report: CheckReport, cell: str, task: str, warnings: list[str]) -> dict[str, Any]:
    """``check --json``'s object."""
    return {
        "ok": report.ok,
        "cell": cell,
        "task": task,
        "params": report.params,
        "cycle_time_s": round(report.plan.cycle_time_s, 4),
        "steps": report.rows(),
        "errors": report.errors,
        "slots_checked": report.checked,
        "failed_slots": [g.to_json() for g in report.slots],
        "warnings": warnings,
        "conveyors": [p.to_json() for p in report.tracking],
    }


def _print(out: Console, title: str, report: CheckReport) -> None:
    """The step table, what was checked and every failure, one clause a line."""
    from rich.text import Text  # human output only: --json needs no rich

    rows = report.rows()
    out.print(step_table(title, [{**r, "message": _headline(r["message"])} for r in rows]))
    for line in report.checked_lines():
        out.print(line, markup=False)
    infeasible = Text("infeasible: ", style="bold red")
    for failure in report.bare:
        out.print(infeasible + Text(_indented(failure.lines())))
    for group in [*report.slots, *report.values]:
        out.print(infeasible + Text(_indented(group.lines())))
    for proof in report.tracking:
        out.print(_indented(proof.summary_lines()), markup=False)
        if proof.error_lines:
            out.print(infeasible + Text(_indented(proof.error_lines)))


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


def _indented(lines: list[str]) -> str:
    """A failure's clauses (each IK branch, the blockers, the fix) indented under its first."""
    first, *rest = lines
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
    except UsageError as exc:
        raise UsageError(f"--watch {exc.message}") from None
    centres = snapshot.occupied_centres()
    if not len(centres):
        return []
    padding = cell.cell.watch.padding if cell.cell.watch is not None else 0.03
    return [Placed("watched zone", Voxels(centres, snapshot.voxel_m, padding), np.eye(4))]
