"""``cellrunner validate CELL [TASK...]``: schema and reference checks only."""

from __future__ import annotations

import argparse
import sys

from cellrunner.errors import Diagnostic, InputError
from cellrunner.model.load import load_cell, load_task, serve_file_warnings
from cellrunner.model.source import display_name


def run(args: argparse.Namespace) -> int:
    errors: list[Diagnostic] = []
    try:
        cell = load_cell(args.cell)
    except InputError as exc:
        raise InputError(exc.diagnostics) from None
    _print(cell.warnings + serve_file_warnings(cell))
    task_paths = args.tasks or [str(cell.resolve(p)) for p in cell.cell.tasks.values()]
    summaries = []
    for path in task_paths:
        try:
            task = load_task(path, cell)
        except InputError as exc:
            errors.extend(exc.diagnostics)
            continue
        _print(task.warnings)
        summaries.append(
            f"{display_name(task.path)}: ok (task {task.name}, {len(task.steps)} steps, "
            f"params: {', '.join(task.task.params) or 'none'})"
        )
    if errors:
        raise InputError(errors)
    c = cell.cell
    sys.stderr.write(
        f"{display_name(cell.path)}: ok (cell {c.cell}, {c.robot.model}, "
        f"{len(c.fixtures)} fixtures, {len(c.frames)} frames, {len(c.parts)} parts, "
        f"{len(c.tasks)} tasks)\n"
    )
    for line in summaries:
        sys.stderr.write(line + "\n")
    return 0


def _print(diagnostics: list[Diagnostic]) -> None:
    for d in diagnostics:
        sys.stderr.write(f"{d}\n")
