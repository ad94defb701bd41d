"""``cellrunner dry-run CELL TASK``: the real cell controller and job runner against the
MuJoCo twin, with faults made to happen physically (``--inject FAULT@STEP``). The
rehearsal itself is :mod:`cellrunner.execution.rehearsal`; this module parses, calls it
and prints."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rich.markup import escape

from cellrunner.backends.factory import make_backend
from cellrunner.cli.common import (
    console,
    emit_json,
    expanded,
    load,
    parse_params,
    record_rows,
    step_table,
)
from cellrunner.cli.faults import parse_injections
from cellrunner.cli.slots import whole_run
from cellrunner.errors import UsageError
from cellrunner.execution.rehearsal import RehearsedJob, start_rehearsal
from cellrunner.model.codes import ResultCode
from cellrunner.model.step import StepKind
from cellrunner.record.attach import finish, record_to_file
from cellrunner.record.files import check_target
from cellrunner.report.recorder import RunRecorder

if TYPE_CHECKING:
    from cellrunner.execution.rehearsal import Rehearsal
    from cellrunner.model.load import LoadedTask
    from cellrunner.model.step import Step


def run(args: argparse.Namespace) -> int:
    if getattr(args, "shift", None):
        from cellrunner.cli.shift import run_shift

        return run_shift(args)
    cell, task = load(args.cell, args.task)
    pairs, whole = whole_run(getattr(args, "slots", None), args.param, task)
    params = parse_params(pairs, task)
    jobs = [params] if whole is None else [{**params, whole[0]: v} for v in whole[1]]
    if whole is not None and args.report:
        raise UsageError("--report rehearses one job; drop --slots (or the -p range) for it")
    recording = check_target(args.record) if getattr(args, "record", None) else None
    steps = expanded(cell, task, jobs[0])
    injections = parse_injections(args.inject, steps)
    if args.report or cell.cell.watch is not None or cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        # before MuJoCo is imported: it reads its GL backend once (a watched cell's depth
        # cameras cast rays instead where there is none; an align step's camera renders)
        enable_pictures()
    # the earlier slots of a place pattern already filled, a part fed before each job of a
    # whole run (SPEC section 12)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=jobs)
    report = Path(args.report) if args.report else None
    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure

        log = configure("json", cell.cell.cell)
    out = console()
    rehearsal = start_rehearsal(
        cell,
        task,
        backend,
        out,
        faults=injections,
        recorder=RunRecorder() if report else None,
        rows_of=record_rows,
        log=log,
        lookahead=not getattr(args, "per_period", False),
    )
    recorder = record_to_file(rehearsal.assembled, recording) if recording else None
    rehearsed = rehearsal.rehearse_all(jobs, task)
    if recorder is not None and recording is not None:
        sys.stderr.write(finish(recorder, recording) + "\n")
    if whole is not None:
        rehearsal.close(getattr(args, "save_map", None))
        return _whole_run_output(args, cell.cell.cell, task.name, whole[0], rehearsed, out)
    job = rehearsed[0]
    has_pictures = _report(rehearsal, job, task, params, steps, report)
    rehearsal.close(getattr(args, "save_map", None))
    _print_job(args, job, task, cell.cell.cell, report, out)
    if not has_pictures:
        from cellrunner.sim.mujoco_loader import GL_ADVICE, no_gl_reason

        out.print(
            f"no pictures in the report: {no_gl_reason()} ({GL_ADVICE} gives one)",
            soft_wrap=True,
        )
    return 0 if job.ok else 1


def _report(
    rehearsal: Rehearsal,
    job: RehearsedJob,
    task: LoadedTask,
    params: dict[str, Any],
    steps: list[Step],
    report: Path | None,
) -> bool:
    """The watched zone's images in the payload; the report written (``report``) with the
    wrist force plot of the force steps. False: the report has no pictures (no GL)."""
    payload, backend = job.payload, rehearsal.backend
    zone = rehearsal.assembled.watch
    if zone is not None:
        payload["depth_images"] = zone.images
        intruders = backend.world.intruders if backend.world is not None else None
        payload["intruders_touched"] = sorted(intruders.touched) if intruders else []
    if report is None:
        return True
    from cellrunner.report import write_report

    assert backend.world is not None  # the run connected the twin
    assert isinstance(rehearsal.recorder, RunRecorder)  # a report records the run
    has_pictures = write_report(
        report,
        rehearsal.recorder,
        payload,
        sim_world=backend.world,
        world=rehearsal.assembled.world,
        task=task,
        params=params,
        step_rows=payload["steps"],
        obstacles_m=(
            zone.map.centres(np.flatnonzero(zone.ever_occupied)) if zone is not None else None
        ),
    )
    runner = rehearsal.controller.last_runner  # finished: the loop no longer touches it
    trace = list(runner.ctx.notes.get("force_trace", [])) if runner else []
    if trace:
        from cellrunner.report.plots import plot_wrist_force

        limits = {
            s.index: s.args.force if s.kind == StepKind.MOVE_UNTIL_CONTACT else s.args.force.max
            for s in steps
            if s.kind in (StepKind.MOVE_UNTIL_CONTACT, StepKind.INSERT)
        }
        plot_wrist_force(
            report / "wrist_force.png",
            trace,
            limits,
            title=f"{task.name}: wrist force in the force steps",
        )
    return has_pictures


def _print_job(
    args: argparse.Namespace,
    job: RehearsedJob,
    task: LoadedTask,
    cell_name: str,
    report: Path | None,
    out: Any,
) -> None:
    """One job's result: its JSON (``--json``), else its step table and summary lines."""
    payload, code = job.payload, job.code
    wall_plan_s, wall_run_s = payload.pop("wall_plan_s"), payload.pop("wall_run_s")
    if args.json:
        emit_json(payload)
        return
    out.print(
        step_table(
            f"dry-run {task.name} on {cell_name} (MuJoCo twin)", payload["steps"], ("attempts",)
        )
    )
    verdict = "[green]OK[/]" if code is ResultCode.OK else f"[bold red]{code.name}[/]"
    out.print(f"result {int(code)} {verdict}: {escape(payload['result_text'])}")
    out.print(
        f"cycle time {payload['cycle_time_s']:.2f} s simulated vs "
        f"{payload['planned_cycle_time_s']:.2f} s planned; "
        f"max tracking error {payload['max_tracking_error_m'] * 1000:.2f} mm; "
        f"retries {payload['retries']}; "
        f"planning {wall_plan_s:.2f} s, simulation {wall_run_s:.2f} s wall "
        f"({payload['real_time_factor']}x real time)"
    )
    if report is not None:
        out.print(f"report written to {report}/index.html", markup=False)


def _whole_run_output(
    args: argparse.Namespace,
    cell_name: str,
    task_name: str,
    param: str,
    rehearsed: list[RehearsedJob],
    out: Any,
) -> int:
    """A row per job (SPEC section 12); ``--json``: one object with a ``jobs`` list."""
    ok = all(j.ok for j in rehearsed)
    first_failed = next((j.payload for j in rehearsed if not j.ok), None)
    payloads = [j.payload for j in rehearsed]
    jobs = [
        {k: v for k, v in p.items() if k not in ("wall_plan_s", "wall_run_s", "cell", "task")}
        for p in payloads
    ]
    if args.json:
        emit_json(
            {
                "ok": ok,
                "cell": cell_name,
                "task": task_name,
                "param": param,
                "result_code": first_failed["result_code"] if first_failed else 0,
                "result_text": first_failed["result_text"] if first_failed else "OK",
                "jobs": jobs,
                "cycle_time_s": round(sum(j["cycle_time_s"] for j in jobs), 4),
                "errors": [
                    f"{param}={j['params'][param]}: {j['result_text']}"
                    for j in jobs
                    if j["result_code"] != 0
                ],
                "parts_end_m": payloads[-1]["parts_end_m"],
            }
        )
        return 0 if ok else 1
    from rich.table import Table

    table = Table(
        title=f"dry-run {task_name} on {cell_name}, {len(jobs)} jobs in one twin",
        title_justify="left",
        pad_edge=False,
    )
    for name, justify in (
        ("job", "right"),
        (param, "right"),
        ("result", "right"),
        ("cycle s", "right"),
        ("planned s", "right"),
        ("message", "left"),
    ):
        table.add_column(name, justify=justify, overflow="fold")  # type: ignore[arg-type]
    for i, j in enumerate(jobs, 1):
        color = "green" if j["result_code"] == 0 else "bold red"
        table.add_row(
            str(i),
            str(j["params"][param]),
            f"[{color}]{j['result_code']}[/]",
            f"{j['cycle_time_s']:.2f}",
            f"{j['planned_cycle_time_s']:.2f}",
            escape(j["result_text"]),
        )
    out.print(table)
    failed = sum(1 for j in jobs if j["result_code"] != 0)
    out.print(
        f"{len(jobs) - failed} of {len(jobs)} jobs OK; "
        f"{sum(j['cycle_time_s'] for j in jobs):.2f} s simulated in all"
    )
    return 0 if ok else 1
