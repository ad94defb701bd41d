"""The demo cell with a job under way on a scripted arm, and a log that keeps every event:
what the hold tests (tests/execution/test_hold_source.py, tests/web/test_page_controls.py)
start from."""

from __future__ import annotations

from typing import Any

from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.model.load import load_cell, load_task
from tests.conftest import DEMO_CELL
from tests.execution.fakes import ScriptedArm, planner, tick


class Recorded:
    """An EventLog that keeps every event: (event, fields)."""

    def __init__(self, events: list[tuple[str, dict[str, Any]]] | None = None) -> None:
        self.events = events if events is not None else []

    def info(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))

    warning = info

    def bind(self, **fields: Any) -> Recorded:
        return self


def held_cell(tmp_path, arm: ScriptedArm) -> tuple[CellController, Recorded, str]:
    """The demo cell with a job under way on ``arm``: (controller, its log, job id)."""
    cell = load_cell(DEMO_CELL)
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    log = Recorded()
    controller = CellController(
        cell, tasks, arm, Journal(tmp_path / "jobs.sqlite"), planner, log=log
    )
    controller.setup()
    tick(controller, 2)
    ticket = controller.start_job(1, {}, "1", "modbus")
    tick(controller)
    assert controller.wait_for_plan(timeout_s=60)
    return controller, log, ticket.job_id
