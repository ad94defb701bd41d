"""``dry-run CELL TASK --shift DURATION [--faults FILE] [--feed-every S] [--seed N]
[--operator-s S] [--progress]``: parse, call :mod:`cellrunner.execution.shift`, print.

The faults file is a mapping of fault to probability per job, e.g.
``{grip_miss: 0.005, protective_stop: 0.001}``."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cellrunner.cli.common import console, emit_json, load, parse_params
from cellrunner.cli.faults import Injection
from cellrunner.cli.slots import whole_run
from cellrunner.cli.stopping import stop_on_signals
from cellrunner.errors import InputError, UsageError
from cellrunner.execution.shift import (
    OPERATOR_S,
    SHIFT_FAULTS,
    Drawn,
    ShiftJob,
    ShiftPlan,
    ShiftRehearsal,
    ShiftReport,
    Timeline,
    parse_duration,
)
from cellrunner.model.load import LoadedCell, LoadedTask


def _belt_feed_every_s(cell: LoadedCell) -> float:
    """A cell whose twin feeds a belt (``sim: {feed: {conveyor, every}}``) brings a part
    every that many s: its shift's jobs start no earlier than their part (0: a part is
    always waiting)."""
    sim = cell.cell.sim
    feed = sim.feed if sim is not None else None
    if feed is None or feed.conveyor is None or feed.every is None:
        return 0.0
    return float(feed.every)


def run_shift(args: argparse.Namespace) -> int:
    try:
        duration_s = parse_duration(args.shift)
    except UsageError as exc:
        raise UsageError(f"--shift: {exc.message}") from None
    if args.inject or args.report or getattr(args, "slots", None):
        raise UsageError("--shift draws its own faults and slots: drop --inject, --report, --slots")
    feed_every_s = float(args.feed_every or 0.0)
    operator_s = float(args.operator_s if args.operator_s is not None else OPERATOR_S)
    if not (math.isfinite(feed_every_s) and feed_every_s >= 0):
        raise UsageError(f"--feed-every {args.feed_every}: give seconds, 0 or more")
    if not (math.isfinite(operator_s) and operator_s >= 0):
        raise UsageError(f"--operator-s {args.operator_s}: give seconds, 0 or more")
    cell, task = load(args.cell, args.task)
    if args.feed_every is None:
        feed_every_s = _belt_feed_every_s(cell)
    rates = load_rates(Path(args.faults)) if args.faults else {}
    slots = _slots(args, task)
    plan = ShiftPlan(duration_s, rates, args.seed, feed_every_s, operator_s)
    out = console()
    shift = ShiftRehearsal(
        plan,
        slots,
        lambda params: _steps(cell, task, params),
        lambda jobs: _rehearse_clean(cell, task, jobs),
        lambda params, drawn: _rehearse_faulted(cell, task, params, drawn),
    )
    with stop_on_signals(exit_code=1) as stop:
        if args.progress:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            with Progress(
                TextColumn("shift"),
                BarColumn(),
                TextColumn("{task.completed:.0f}/{task.total:.0f} s simulated"),
                TimeElapsedColumn(),
                console=out,
            ) as bar:
                row = bar.add_task("shift", total=duration_s)
                report = shift.run(lambda s: bar.update(row, completed=s), stop.event.is_set)
        else:
            with out.status("rehearsing the shift", spinner="dots"):
                report = shift.run(stop=stop.event.is_set)
    payload = {
        "cell": cell.cell.cell,
        "task": task.name,
        **report.to_json(lambda job: replay_command(args, job)),
    }
    if stop.event.is_set():
        payload["ok"] = False
        payload["errors"] = [f"stopped by {stop.signal_name} after {len(report.jobs)} jobs"]
    if args.json:
        emit_json(payload)
    else:
        _print(out, payload, report)
    return 0 if payload["ok"] else 1


def load_rates(path: Path, known: tuple[str, ...] = SHIFT_FAULTS) -> dict[str, float]:
    """The faults file: fault -> probability per job (0..1), each one of ``known``;
    located errors otherwise."""
    from cellrunner.model.source import load_yaml

    source = load_yaml(path)
    data = source.data
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(
            [source.diagnostic((), "write a mapping of fault to rate, e.g. {grip_miss: 0.005}")]
        )
    problems = []
    rates: dict[str, float] = {}
    for name, value in data.items():
        if name not in known:
            problems.append(
                source.diagnostic(
                    (name,),
                    f"unknown fault {name!r}; known: {', '.join(known)}"
                    if name not in SHIFT_FAULTS
                    else f"{name} is not a fault serve makes happen; known: {', '.join(known)}",
                    at_key=True,
                )
            )
        elif isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= 1:
            problems.append(
                source.diagnostic(
                    (name,), f"{name}: {value!r} is not a rate per job; give 0..1 (e.g. 0.005)"
                )
            )
        else:
            rates[str(name)] = float(value)
    if problems:
        raise InputError(problems)
    return rates


def replay_command(args: argparse.Namespace, job: ShiftJob) -> str:
    """The command line that rehearses ``job`` alone with its faults."""
    words = ["cellrunner", "dry-run", str(args.cell), str(args.task)]
    for name, value in job.params.items():
        words += ["-p", f"{name}={value}"]
    for fault, index in job.faults:
        words += ["--inject", f"{fault}@{index}"]
    return shlex.join(words)


def _slots(args: argparse.Namespace, task: LoadedTask) -> list[dict[str, Any]]:
    """One params dict per slot of the task's pattern (one, without a pattern)."""
    try:
        pairs, whole = whole_run("all", args.param, task)
    except UsageError:  # no single pattern param: the same job each time
        pairs, whole = args.param, None
    params = parse_params(pairs, task)
    if whole is None:
        return [params]
    name, values = whole
    return [{**params, name: v} for v in values]


def _steps(cell: LoadedCell, task: LoadedTask, params: dict[str, Any]) -> Sequence[Any]:
    from cellrunner.model.job_steps import job_steps

    return job_steps(task, cell.cell, params)


def _quiet() -> Any:
    from rich.console import Console

    return Console(file=io.StringIO(), highlight=False)


def _rehearse(
    cell: LoadedCell, task: LoadedTask, jobs: Sequence[dict[str, Any]], faults: list[Injection]
) -> list[Timeline]:
    from cellrunner.backends.factory import make_backend
    from cellrunner.cli.common import record_rows
    from cellrunner.execution.rehearsal import start_rehearsal

    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=list(jobs))
    rehearsal = start_rehearsal(cell, task, backend, _quiet(), faults=faults, rows_of=record_rows)
    try:
        return [Timeline.of(j.payload) for j in rehearsal.rehearse_all(list(jobs), task)]
    finally:
        with contextlib.suppress(Exception):
            rehearsal.close()


def _rehearse_clean(
    cell: LoadedCell, task: LoadedTask, jobs: Sequence[dict[str, Any]]
) -> list[Timeline]:
    """Each slot's job with no fault, in order, in one twin (a whole run)."""
    return _rehearse(cell, task, jobs, [])


def _rehearse_faulted(
    cell: LoadedCell, task: LoadedTask, params: dict[str, Any], drawn: Drawn
) -> Timeline:
    """One job with its faults from a fresh twin: what its replay command line does."""
    faults = [Injection(f, i, f"{f}@{i}") for f, i in drawn]
    return _rehearse(cell, task, [params], faults)[0]


def _print(out: Any, payload: dict[str, Any], report: ShiftReport) -> None:
    from rich.markup import escape
    from rich.table import Table

    hours = payload["shift_s"] / 3600.0
    table = Table(
        title=f"shift of {hours:g} h: {payload['task']} on {payload['cell']} (seed {payload['seed']})",
        title_justify="left",
        pad_edge=False,
    )
    table.add_column("figure")
    table.add_column("value", justify="right")

    def opt(value: float | None, unit: str) -> str:
        return "no failure" if value is None else f"{value:,.0f} {unit}"

    for name, value in (
        ("jobs", f"{payload['jobs']:,}"),
        ("parts good", f"{payload['parts_good']:,}"),
        ("parts bad", f"{payload['parts_bad']:,}"),
        ("parts per hour", f"{payload['parts_per_hour']:,.1f}"),
        ("availability", f"{payload['availability'] * 100:.2f} %"),
        ("MTBF", opt(payload["mtbf_s"], "s")),
        ("MTTR", opt(payload["mttr_s"], "s")),
        (
            "faults drawn",
            ", ".join(f"{k} {v}" for k, v in payload["faults_drawn"].items()) or "none",
        ),
        ("recovered by the engine", str(payload["recovered"])),
        ("results", ", ".join(f"{k}: {v}" for k, v in payload["results"].items())),
    ):
        table.add_row(name, escape(value))
    out.print(table)
    steps = Table(title="slowest steps", title_justify="left", pad_edge=False)
    for name, justify in (
        ("step", "left"),
        ("mean s", "right"),
        ("max s", "right"),
        ("runs", "right"),
    ):
        steps.add_column(name, justify=justify)  # type: ignore[arg-type]
    for s in payload["slowest_steps"]:
        steps.add_row(
            escape(f"{s['kind']} {s['name']}"),
            f"{s['mean_s']:.3f}",
            f"{s['max_s']:.3f}",
            str(s["runs"]),
        )
    out.print(steps)
    for r in payload["replay"]:
        out.print(
            f"first {escape(r['kind'])}: job {r['job']}: {escape(r['result_text'])}\n"
            f"  replay: {escape(r['command'])}",
            soft_wrap=True,
        )
    out.print(
        f"{payload['rehearsed_jobs']} distinct jobs rehearsed in the twin, "
        f"{report.wall_s:.1f} s wall for {hours:g} h simulated"
    )
    for error in payload.get("errors", []):
        out.print(f"[bold red]{escape(error)}[/]")
