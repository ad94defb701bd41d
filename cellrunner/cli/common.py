"""Shared pieces of the commands: loading a cell and task, params from -p, output."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cellrunner.errors import InputError, UsageError
from cellrunner.model.expand import Step, resolve_params
from cellrunner.model.job_steps import job_steps
from cellrunner.model.load import LoadedCell, LoadedTask, load_cell, load_task
from cellrunner.model.params import ParamValue

if TYPE_CHECKING:
    from rich.console import Console, JustifyMethod
    from rich.table import Table

    from cellrunner.execution.job_view import JobView

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def load(cell_path: str | None, task_path: str | None) -> tuple[LoadedCell, LoadedTask]:
    """The cell and task, every problem of both reported at once (exit 2). Without
    either, the embedded example (a UR5e pick-and-place) is used."""
    if cell_path is None:
        cell_path = str(EXAMPLES / "cells" / "demo_ur5e.yaml")
        task_path = task_path or str(EXAMPLES / "tasks" / "pick_place.yaml")
    elif task_path is None:
        raise UsageError("give the TASK file after the CELL file")
    cell = load_cell(cell_path)
    task = load_task(task_path, cell)
    for warning in [*cell.warnings, *task.warnings]:
        sys.stderr.write(f"{warning}\n")
    return cell, task


def parse_params(pairs: list[str], task: LoadedTask) -> dict[str, Any]:
    """``["slot=3"]`` -> the task's typed params, defaults filled in."""
    given: dict[str, str] = {}
    for pair in pairs:
        if "=" not in pair:
            raise UsageError(f"-p {pair!r}: write -p NAME=VALUE")
        key, value = pair.split("=", 1)
        given[key.strip()] = value.strip()
    try:
        return resolve_params(task.task, given)
    except InputError as exc:
        raise UsageError(exc.diagnostics[0].message) from None


def expanded(cell: LoadedCell, task: LoadedTask, params: dict[str, ParamValue]) -> list[Step]:
    return job_steps(task, cell.cell, params)


def emit_json(payload: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(payload, indent=2, default=_default) + "\n")


def _default(value: object) -> object:
    import numpy as np

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(type(value).__name__)


def console() -> Console:
    """A rich console on stderr (human output never pollutes --json on stdout)."""
    from rich.console import Console

    return Console(stderr=True, highlight=False)


def step_table(
    title: str, rows: list[dict[str, Any]], extra_columns: tuple[str, ...] = ()
) -> Table:
    from rich.table import Table
    from rich.text import Text

    table = Table(title=title, title_justify="left", show_lines=False, pad_edge=False)
    columns: tuple[tuple[str, JustifyMethod], ...] = (
        ("#", "right"),
        ("kind", "left"),
        ("name", "left"),
        ("time s", "right"),
        ("status", "left"),
        *[(c, "right") for c in extra_columns],
        ("message", "left"),
    )
    for name, justify in columns:
        table.add_column(name, justify=justify, overflow="fold")
    colors = {"ok": "green", "failed": "bold red", "not planned": "dim", "skipped": "dim"}
    for r in rows:
        status = r["status"]
        table.add_row(
            str(r["index"]),
            r["kind"],
            Text(r["name"]),
            f"{r['duration_s']:.2f}",
            Text(status, style=colors.get(status, "yellow")),
            *[str(r.get(c.replace(" ", "_"), "")) for c in extra_columns],
            Text(r.get("message", "")),
        )
    return table


def record_rows(job: JobView | None, steps: list[Step] | None = None) -> list[dict[str, Any]]:
    """The ``steps`` of a ``--json`` report from a job's step records (a
    :class:`~cellrunner.execution.job_view.JobView`; rows with status "not run" for ``steps``
    when the job has none, e.g. planning failed)."""
    records = () if job is None else job.records
    if isinstance(records, dict):  # a JobRunner's own records
        records = tuple(records.values())
    if not records:
        return [
            {
                "index": s.index,
                "name": s.name,
                "kind": s.kind,
                "duration_s": 0.0,
                "status": "not run",
                "message": "",
                "attempts": 0,
            }
            for s in steps or []
        ]
    return [
        {
            "index": r.index,
            "name": r.name,
            "kind": r.kind,
            "duration_s": round(r.duration_s, 4),
            "status": str(r.status),
            "message": r.message,
            "attempts": r.attempts,
        }
        for r in records
    ]
