"""The status snapshot the page and the metrics are drawn from.

:class:`StatusBoard` reads the cell only through its public ``status()`` (cheap, a
copy taken under the engine's lock) and the journal through its *own* connection, so
serving a page never waits on the control loop or the PLC link, and the control loop
never waits on a browser. Snapshots are cached for ``max_age_s`` so that many open
pages cost one journal query.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from cellrunner.execution.journal import JobRecord, JournalBackend
from cellrunner.model.cellport import CellPort, CellStatus
from cellrunner.web.alarms import active_alarms
from cellrunner.web.metrics import JobMetrics, render

#: finished jobs shown as the last results, and in the cycle time trend
LAST_RESULTS = 10
TREND_JOBS = 40


class StatusBoard:
    """Builds snapshots of one cell. ``plc_links`` returns ``{link: up}`` for each
    configured PLC link (empty when none is configured)."""

    def __init__(
        self,
        port: CellPort,
        journal: JournalBackend,
        cell_name: str,
        *,
        plc_links: Callable[[], dict[str, bool]] = dict,
        max_age_s: float = 0.2,
    ) -> None:
        self.port, self.journal, self.cell_name = port, journal, cell_name
        self.plc_links = plc_links
        self.max_age_s = max_age_s
        self.jobs = JobMetrics()
        self._lock = threading.Lock()
        self._cached: tuple[float, dict[str, Any]] | None = None
        self._remove_listener: Callable[[], None] | None = None

    def setup(self) -> StatusBoard:
        """Open the journal connection and start counting finished jobs."""
        self.journal.open()
        self._remove_listener = self.port.add_result_listener(self.jobs.record)
        return self

    def close(self) -> None:
        if self._remove_listener is not None:
            self._remove_listener()
            self._remove_listener = None
        self.journal.close()

    def metrics(self) -> str:
        """The Prometheus text page (no journal query: status and counters only)."""
        return render(self.cell_name, self.port.status(), self.jobs, self._links())

    def snapshot(self) -> dict[str, Any]:
        """The JSON-ready status of the cell (cached for ``max_age_s``)."""
        with self._lock:
            now = time.monotonic()
            if self._cached is None or now - self._cached[0] > self.max_age_s:
                self._cached = (now, self._build())
            return self._cached[1]

    def _build(self) -> dict[str, Any]:
        status = self.port.status()
        links = self._links()
        try:
            job = self._job(status)
            recent = self.journal.last(TREND_JOBS + 1)
            journal_error = ""
        except Exception as exc:  # the page still shows the state when the journal is away
            job, recent, journal_error = None, [], f"{type(exc).__name__}: {exc}"
        finished = [r for r in recent if r.ended_at is not None]
        return {
            "cell": self.cell_name,
            "time": datetime.now(UTC).isoformat(timespec="seconds"),
            "state": {"number": status.state, "name": status.state_name},
            "ready": status.ready,
            "busy": status.busy,
            "held": status.held,
            "protective_stop": status.protective_stop,
            "estop": status.estop,
            "obstructed": status.obstructed,
            "obstruction": status.obstruction,
            "hold_source": status.hold_source,
            "hold_reason": status.hold_reason,
            "plc_links": links,
            "job": job,
            "last_results": [_result_row(r) for r in reversed(finished[-LAST_RESULTS:])],
            "cycle_times": [
                {"job_id": r.job_id, "cycle_time_s": r.cycle_time_s, "result_code": r.result_code}
                for r in finished[-TREND_JOBS:]
                if r.cycle_time_s
            ],
            "parts": {"processed": status.parts_processed, "defective": status.parts_defective},
            "alarms": [a.to_json() for a in active_alarms(status, links)],
            "journal_error": journal_error,
        }

    def _job(self, status: CellStatus) -> dict[str, Any] | None:
        if not status.job_id:
            return None
        record = self.journal.get(status.job_id)
        rows = self.journal.steps_of(status.job_id)
        steps: dict[int, dict[str, Any]] = {}
        for index, kind, name, step_status, attempt, _at, message in rows:
            steps[index] = {
                "index": index,
                "kind": kind,
                "name": name,
                "status": step_status,
                "attempt": attempt,
                "message": message or "",
            }
        current = steps.get(status.step_index)
        return {
            "job_id": status.job_id,
            "task": record.task if record else "",
            "params": record.params if record else {},
            "source": record.source if record else "",
            "client_job_id": (record.client_job_id or "") if record else "",
            "elapsed_s": round(time.time() - record.started_at, 1) if record else None,
            "step_index": status.step_index,
            "step": current,
            "steps": [steps[i] for i in sorted(steps)],
        }

    def _links(self) -> dict[str, bool]:
        try:
            return dict(self.plc_links())
        except Exception:  # the PLC service's own failure: the page still shows the cell
            return {}


def _result_row(r: JobRecord) -> dict[str, Any]:
    assert r.ended_at is not None  # a result is a finished job
    return {
        "job_id": r.job_id,
        "task": r.task,
        "params": r.params,
        "source": r.source,
        "client_job_id": r.client_job_id or "",
        "result_code": r.result_code,
        "result_text": r.result_text or "",
        "cycle_time_s": r.cycle_time_s,
        "retries": r.retries,
        # why the planner refused it, as data (None for any other end)
        "failure": r.failure.to_json() if r.failure else None,
        "failure_brief": r.failure.brief() if r.failure else "",
        "ended_at": datetime.fromtimestamp(r.ended_at, UTC).isoformat(timespec="seconds"),
    }
