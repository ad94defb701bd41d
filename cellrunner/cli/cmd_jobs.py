"""``cellrunner jobs CELL [--last N] [--csv] [--all-cells]``: the journal (the cell's
jobs; with ``--all-cells`` every cell's in a shared journal, e.g. a plant-wide
PostgreSQL one)."""

from __future__ import annotations

import argparse
import csv
import sys
from datetime import datetime

from cellrunner.errors import UsageError
from cellrunner.execution.journal import display_location, is_database_url
from cellrunner.execution.journal_open import cell_journal
from cellrunner.model.load import load_cell

COLUMNS = (
    "job_id",
    "started",
    "task",
    "params",
    "source",
    "client_job_id",
    "result_code",
    "result_text",
    "cycle_time_s",
    "retries",
    # why the planner refused a job, as data (empty for any other end, and in old journals)
    "failure_kind",
    "failure_step",
    "blockers",
)


def run(args: argparse.Namespace) -> int:
    if args.last < 1:
        raise UsageError(f"--last {args.last}: give a positive number of jobs")
    cell = load_cell(args.cell)
    all_cells = getattr(args, "all_cells", False)
    where = cell.cell.journal
    if not is_database_url(where):
        path = cell.resolve_output(where)
        if not path.exists():
            sys.stderr.write(f"{path}: no journal yet (no job has run)\n")
            return 0
        where = str(path)
    journal = cell_journal(cell, all_cells=all_cells).open()
    try:
        records = journal.last(args.last)
    finally:
        journal.close()
    columns = ("cell", *COLUMNS) if all_cells else COLUMNS
    rows = [
        {
            "cell": r.cell,
            "job_id": r.job_id,
            "started": _time(r.started_at),
            "task": r.task,
            "params": " ".join(f"{k}={v}" for k, v in r.params.items()),
            "source": r.source,
            "client_job_id": r.client_job_id or "",
            "result_code": "" if r.result_code is None else r.result_code,
            "result_text": r.result_text or ("running" if r.ended_at is None else ""),
            "cycle_time_s": "" if r.cycle_time_s is None else f"{r.cycle_time_s:.2f}",
            "retries": r.retries,
            "failure_kind": r.failure.kind.value if r.failure else "",
            "failure_step": ""
            if r.failure is None or r.failure.step_index is None
            else r.failure.step_index,
            "blockers": r.failure.blockers_text() if r.failure else "",
            "failure": r.failure.brief() if r.failure else "",
        }
        for r in records
    ]
    if args.csv:
        writer = csv.DictWriter(sys.stdout, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
        return 0
    from rich.table import Table

    from cellrunner.cli.common import console

    # the table shows a refusal's kind, step and blockers in one column, when there is one
    columns = (
        *columns[: -len(_FAILURE_COLUMNS)],
        *(("failure",) if any(r.failure for r in records) else ()),
    )
    whose = "all cells" if all_cells else cell.cell.cell
    table = Table(title=f"jobs of {whose} ({display_location(where)})", title_justify="left")
    from rich.text import Text

    id_width = max([len(str(row["job_id"])) for row in rows], default=6)
    for c in columns:  # a job id is never cut (it is what one looks up); the other columns fold
        table.add_column(
            c,
            justify="right" if c in ("result_code", "cycle_time_s", "retries") else "left",
            no_wrap=c == "job_id",
            min_width=id_width if c == "job_id" else None,
            overflow="fold",
        )
    for row in rows:
        table.add_row(*[Text(str(row[c])) for c in columns])
    console().print(table)
    return 0


_FAILURE_COLUMNS = ("failure_kind", "failure_step", "blockers")


def _time(ts: float) -> str:
    return datetime.fromtimestamp(ts).strftime("%Y-%m-%d %H:%M:%S")
