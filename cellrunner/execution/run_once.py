"""One job on an assembled cell, from connecting to closing: what ``cellrunner run`` does
between reading its arguments and printing the result, callable without the CLI."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cellrunner.execution.assembly import AssembledCell
from cellrunner.execution.job_view import JobView
from cellrunner.model.cellport import JobResult


@dataclass(frozen=True)
class OneJob:
    """How the job went: ``refused`` (the cell's reason) when it never started, else the
    job as it ended and its result."""

    refused: str = ""
    job: JobView | None = None
    result: JobResult | None = None


def run_one_job(
    assembled: AssembledCell,
    params: dict[str, Any],
    *,
    stop: threading.Event,
    stop_reason: Callable[[], str],
    max_s: float,
    on_refused: Callable[[str], object] | None = None,
    before: Callable[[], None] | None = None,
    while_running: Callable[[], contextlib.AbstractContextManager[Any]] = contextlib.nullcontext,
    on_close: Callable[[], None] | None = None,
) -> OneJob:
    """Connect, run task 1 with ``params`` (for at most ``max_s``, or until ``stop`` is
    set: then the arm is stopped and the job closed with ``stop_reason()``), close.

    ``on_refused`` hears a refusal before anything is closed, ``before`` runs once the job
    was accepted, ``while_running`` wraps the run (a spinner), ``on_close`` runs after
    the cell closed (a recording's last words)."""
    controller, loop = assembled.controller, assembled.loop
    controller.setup()
    try:
        if assembled.feed is not None:
            assembled.feed.start()
        loop.step(5)
        ticket = controller.start_job(1, params, "", "cli")
        if not ticket.accepted:
            if on_refused is not None:
                on_refused(ticket.message)
            return OneJob(refused=ticket.message)
        if before is not None:
            before()
        with while_running():
            loop.run_job(max_s=max_s, stop=stop)
        if stop.is_set():
            controller.shutdown(stop_reason())
        return OneJob(job=controller.last_job, result=controller.status().last_result)
    finally:
        if assembled.feed is not None:
            assembled.feed.close()
        controller.close()
        if on_close is not None:
            on_close()
