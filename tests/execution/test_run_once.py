"""The job a ``run`` runs and the cell ``serve`` serves, called without the CLI."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.run_once import run_one_job
from cellrunner.execution.serving import Closer, serve
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from tests.rig import CELL, TASK, write_cell


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return write_cell(tmp_path_factory.mktemp("project"), CELL, TASK)


class _Log:
    """Keeps the events it is given (what serve tells the operator)."""

    def __init__(self) -> None:
        self.events: list[tuple[str, dict[str, Any]]] = []

    def info(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))

    warning = exception = info

    def bind(self, **fields: Any) -> _Log:
        return self


def _assembled(project: tuple[Path, Path], log: Any = None) -> Any:
    cell = load_cell(project[0])
    return assemble_cell(cell, {1: load_task(project[1], cell)}, "sim", log=log)


def test_one_job_runs_to_its_end_and_the_cell_is_closed(project: tuple[Path, Path]) -> None:
    closed: list[str] = []
    ran = run_one_job(
        _assembled(project),
        {},
        stop=threading.Event(),
        stop_reason=lambda: "never",
        max_s=600.0,
        on_refused=closed.append,
        on_close=lambda: closed.append("closed"),
    )
    assert not ran.refused and ran.job is not None and ran.result is not None
    assert ran.job.result_code is ResultCode.OK and ran.result.cycle_time_s > 1.0
    assert closed == ["closed"]


def test_a_refused_job_says_why_before_the_cell_closes(project: tuple[Path, Path]) -> None:
    heard: list[str] = []
    ran = run_one_job(
        _assembled(project),
        {"no_such_param": 1.0},
        stop=threading.Event(),
        stop_reason=lambda: "never",
        max_s=600.0,
        on_refused=lambda why: heard.append(f"refused: {why}"),
        on_close=lambda: heard.append("closed"),
    )
    assert ran.refused and ran.job is None
    assert heard == [f"refused: {ran.refused}", "closed"]


def test_serve_opens_its_links_and_closes_them_last_first_when_stopped(
    project: tuple[Path, Path],
) -> None:
    log = _Log()
    stop = threading.Event()
    order: list[str] = []

    def open_links(closers: list[Closer]) -> None:
        closers.append(lambda: order.append("plc"))
        closers.append(lambda: order.append("page"))

    def on_serving() -> None:
        order.append("serving")
        stop.set()  # the loop sees it at its first look

    serve(
        _assembled(project, log),
        stop,
        log,
        stop_reason=lambda: "cellrunner stopped (SIGTERM)",
        open_links=open_links,
        on_serving=on_serving,
        on_stopped=lambda: order.append("stopped"),
    )
    assert order == ["serving", "stopped", "page", "plc"]
    assert ("stopped", {"reason": "cellrunner stopped (SIGTERM)"}) in log.events
