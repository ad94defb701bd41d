"""The cell's jobs in its journal (SPEC section 9): a job is journaled before it is
acknowledged, each step row as it changes, its end with its result code; a job a
restart interrupted is closed with 107. A journal that cannot be written refuses new
jobs but never stops one under way; a job's result is told to the PLC once it is written
(a full disk holds it), or at once when the journal refused it for good."""

from __future__ import annotations

import sqlite3
import threading
from typing import TYPE_CHECKING, Any

from cellrunner.execution.job_view import Job, result_of_record
from cellrunner.execution.journal import JournalBackend, JournalError
from cellrunner.model.cellport import JobResult, JobTicket
from cellrunner.model.codes import ResultCode

if TYPE_CHECKING:
    from cellrunner.execution.context import EventLog
    from cellrunner.execution.job_records import StepRecord


class JobBook:
    """Writes a cell's jobs to ``journal``; ``counters`` are (parts processed, defective)."""

    def __init__(self, journal: JournalBackend, cell_name: str, log: EventLog | None) -> None:
        self.journal, self.cell_name, self.log = journal, cell_name, log
        self.counters = (0, 0)

    def open(self) -> JobResult | None:
        """Open the journal, close the jobs a restart interrupted (107); the last result."""
        self.journal.open()
        interrupted = self.journal.close_interrupted()
        last = interrupted[-1] if interrupted else self.journal.last_finished()
        self.counters = self.journal.counters()
        return result_of_record(last) if last is not None else None

    def first_of(self, source: str, client_job_id: str) -> JobTicket | None:
        """OPC UA's StartJob sent again with the same ClientJobId: the first job's ticket
        (None: a new job); not ready when the journal cannot be read."""
        if source != "opcua" or not client_job_id:
            return None
        try:
            first = self.journal.by_client_id(source, client_job_id)
        except JournalError as exc:
            return JobTicket("", ResultCode.REJECT_NOT_READY, f"not ready: {exc}")
        if first is None:
            return None
        return JobTicket(first.job_id, ResultCode.OK, "the same ClientJobId again: the first job")

    def begin(self, job: Job) -> JobTicket | None:
        """Journal ``job`` before it is acknowledged; a refusal when that fails."""
        try:
            self.journal.begin_job(
                job.job_id, self.cell_name, job.task.name, job.params, job.source, job.client_job_id
            )
        except (JournalError, sqlite3.Error) as exc:  # database away, disk full, read-only
            self._log("journal_failed", error=str(exc))
            return JobTicket(
                "", ResultCode.REJECT_NOT_READY, f"not ready: the journal cannot be written: {exc}"
            )
        return None

    def step(self, job: Job, record: StepRecord, attempt: int) -> None:
        try:
            self.journal.step(
                job.job_id,
                record.index,
                record.kind,
                record.name,
                record.status,
                attempt,
                record.message,
            )
        except sqlite3.Error as exc:  # disk full: the job goes on; its row is missing a step
            self._log("journal_failed", job_id=job.job_id, error=str(exc))

    def end(
        self, job: Job, code: ResultCode, cycle_s: float, retries: int, message: str
    ) -> threading.Event:
        """Journal ``job``'s end; the event is set once the result is written (a full disk
        holds it until there is room), or at once when the journal refused it for good."""
        try:
            return self.journal.end_job(job.job_id, code, cycle_s, retries, message)
        except (JournalError, sqlite3.Error) as exc:  # refused for good: the PLC still hears
            self._warn("journal_failed", job_id=job.job_id, error=str(exc))
            durable = threading.Event()
            durable.set()
            return durable

    def refresh_counters(self) -> None:
        self.counters = self.journal.counters()

    def held(self) -> list[str]:
        """The results the journal has not written yet (a full disk)."""
        return self.journal.held()

    @property
    def last_error(self) -> str:
        return str(getattr(self.journal, "last_error", ""))

    def close(self) -> None:
        self.journal.close()

    def _log(self, event: str, **kw: Any) -> None:
        if self.log is not None:
            self.log.info(event, **kw)

    def _warn(self, event: str, **kw: Any) -> None:
        if self.log is not None:
            self.log.warning(event, **kw)
