"""``cellrunner replay FILE.rrd|FILE.mcap`` opens a recording in Rerun's viewer (or says how
to open it where there is no display); ``cellrunner replay CELL|JOURNAL JOB_ID`` opens the
job's recording when ``--recordings DIR`` kept one, else writes the job's HTML report
from the journal (its steps, their results and times)."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from cellrunner.errors import InputError, UsageError
from cellrunner.record.files import SUFFIXES


def run(args: argparse.Namespace) -> int:
    source = Path(args.source)
    if args.job_id is None:
        if source.suffix not in SUFFIXES:
            raise UsageError(
                f"replay {args.source}: give FILE.rrd, FILE.mcap, or CELL|JOURNAL JOB_ID"
            )
        if not source.is_file():
            raise InputError("no such recording", file=source)
        return open_recording(source)
    if args.recordings:
        for suffix in SUFFIXES:
            kept = Path(args.recordings) / f"{args.job_id}{suffix}"
            if kept.is_file():
                return open_recording(kept)
    return _report(args, source)


def open_recording(path: Path) -> int:
    """Rerun's viewer on ``path`` (it reads .rrd and .mcap) when there is one and a display;
    otherwise how to open it."""
    viewer = shutil.which("rerun") or shutil.which("rerun", path=str(Path(sys.executable).parent))
    display = sys.platform in ("darwin", "win32") or any(
        os.environ.get(v) for v in ("DISPLAY", "WAYLAND_DISPLAY")
    )
    if viewer is not None and display:
        subprocess.Popen([viewer, str(path)], start_new_session=True)  # the viewer outlives us
        print(f"opened {path} in Rerun's viewer")
        return 0
    why = "no display here" if viewer is not None else "Rerun's viewer is not installed"
    print(f"{path}: {why}. To open it:")
    print(f"  rerun {path}                      (pip install 'cellrunner[record]')")
    print(f"  rerun --web-viewer {path}         (in a browser)")
    if path.suffix == ".mcap":
        print("  Foxglove: Open local file... (app.foxglove.dev or the desktop app)")
    return 0


def _report(args: argparse.Namespace, source: Path) -> int:
    from cellrunner.execution.journal_open import cell_journal, journal_for

    if source.suffix in (".yaml", ".yml"):
        from cellrunner.model.load import load_cell

        journal = cell_journal(load_cell(str(source)), all_cells=True)
    elif "://" in args.source or source.is_file():
        journal = journal_for(args.source, None)
    else:
        raise InputError("no such cell file or journal", file=source)
    journal.open()
    try:
        job = journal.get(args.job_id)
        if job is None:
            raise UsageError(f"replay: no job {args.job_id} in the journal {args.source}")
        rows = _step_rows(journal.steps_of(args.job_id))
    finally:
        journal.close()
    from cellrunner.report.page import write_index

    folder = Path(args.out or f"report-{args.job_id}")
    folder.mkdir(parents=True, exist_ok=True)
    payload: dict[str, Any] = {
        "ok": job.result_code == 0,
        "cell": job.cell,
        "task": job.task,
        "params": job.params,
        "result_code": job.result_code,
        "result_text": job.result_text or "(interrupted)",
        "cycle_time_s": job.cycle_time_s or 0.0,
        "retries": job.retries,
    }
    notes = [f"job {job.job_id} from the journal (source {job.source}); no recording kept"]
    path = write_index(folder, payload, rows, [], [], None, notes)
    print(f"wrote {path}")
    return 0


def _step_rows(rows: list[tuple[Any, ...]]) -> list[dict[str, Any]]:
    """The report's step rows from the journal's step transitions (index, kind, name,
    status, attempt, at, message), one row per step: its last status, attempts and the
    time from its first transition to its last."""
    steps: dict[int, dict[str, Any]] = {}
    for index, kind, name, status, attempt, at, message in rows:
        row = steps.setdefault(
            index,
            {"index": index, "kind": kind, "name": name, "planned_s": 0.0, "first": at},
        )
        row.update(status=status, attempts=attempt, message=message or "")
        row["duration_s"] = float(at) - float(row["first"])
    return [{k: v for k, v in r.items() if k != "first"} for _, r in sorted(steps.items())]
