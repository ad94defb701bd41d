"""The cell's jobs in its journal (SPEC section 9): a job is journaled before it is
acknowledged, each step row as it changes, its end with its result code; a job a
restart interrupted is closed with 107. A journal that cannot be written refuses new
jobs but never stops one under way; a job's result is told to the PLC once it is written
(a full disk holds it), or at once when the journal refused it for good."""

from __future__ import annotations

import contextlib
import sqlite3
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from cellrunner.execution.context import QUIET, EventLog
from cellrunner.execution.job_view import Job, result_of_job, result_of_record
from cellrunner.execution.journal import JournalBackend, JournalError
from cellrunner.model.cellport import JobResult, JobSource, JobTicket, ResultListener
from cellrunner.model.codes import ResultCode
from cellrunner.model.failure import Failure

if TYPE_CHECKING:
    from cellrunner.execution.job_records import StepRecord


class JobBook:
    """Writes a cell's jobs to ``journal`` and tells their results: ``last`` is the last
    result told, ``counters`` (parts processed, defective). ``publish`` is called once a
    result is written, before the result listeners hear it."""

    def __init__(
        self,
        journal: JournalBackend,
        cell_name: str,
        log: EventLog | None,
        publish: Callable[[], None],
    ) -> None:
        self.journal, self.cell_name, self.log = journal, cell_name, log or QUIET
        self.publish = publish
        self.counters = (0, 0)
        self.last: JobResult | None = None
        self.listeners: list[ResultListener] = []
        # a result the journal has not written yet (a full disk), and its "written" event
        self._held: tuple[JobResult, threading.Event] | None = None

    @property
    def holding(self) -> bool:
        """A result waits for the journal (a full disk): no new job until it is written."""
        return self._held is not None

    def open(self) -> None:
        """Open the journal, close the jobs a restart interrupted (107), read the last
        result."""
        self.journal.open()
        interrupted = self.journal.close_interrupted()
        last = interrupted[-1] if interrupted else self.journal.last_finished()
        self.counters = self.journal.counters()
        if last is not None:
            self.last = result_of_record(last)

    def first_of(self, source: JobSource, client_job_id: str) -> JobTicket | None:
        """A request sent again with the same client job id, by a requester whose ids name
        jobs (OPC UA's StartJob): the first job's ticket (None: a new job); not ready when
        the journal cannot be read."""
        if not source.ids_name_jobs or not client_job_id:
            return None
        try:
            first = self.journal.by_client_id(source.name, client_job_id)
        except JournalError as exc:
            return JobTicket("", ResultCode.REJECT_NOT_READY, f"not ready: {exc}")
        if first is None:
            return None
        return JobTicket(first.job_id, ResultCode.OK, "the same ClientJobId again: the first job")

    def finished(self, source: str, client_job_id: str) -> JobResult | None:
        """How the job ``source`` named ``client_job_id`` ended, as the journal has it
        (None: no such job, not ended yet, or the journal cannot be read)."""
        if not client_job_id:
            return None
        try:
            record = self.journal.by_client_id(source, client_job_id)
        except (JournalError, sqlite3.Error):
            return None
        if record is None or record.result_code is None:
            return None
        return result_of_record(record)

    def begin(self, job: Job) -> JobTicket | None:
        """Journal ``job`` before it is acknowledged; a refusal when that fails."""
        try:
            self.journal.begin_job(
                job.job_id, self.cell_name, job.task.name, job.params, job.source, job.client_job_id
            )
        except (JournalError, sqlite3.Error) as exc:  # database away, disk full, read-only
            self.log.info("journal_failed", error=str(exc))
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
            self.log.info("journal_failed", job_id=job.job_id, error=str(exc))

    def end(
        self,
        job: Job,
        code: ResultCode,
        cycle_s: float,
        retries: int,
        message: str,
        failure: Failure | None = None,
    ) -> None:
        """Journal ``job``'s end and tell its result once it is written (a full disk holds
        it until there is room: :meth:`deliver` tells it then), or at once when the journal
        refused it for good."""
        try:
            durable = self.journal.end_job(job.job_id, code, cycle_s, retries, message, failure)
        except (JournalError, sqlite3.Error) as exc:  # refused for good: the PLC still hears
            self.log.warning("journal_failed", job_id=job.job_id, error=str(exc))
            durable = threading.Event()
            durable.set()
        self._held = (result_of_job(job, code, message, cycle_s, retries, failure), durable)
        if not self.deliver():
            self.log.warning(
                "result_held", job_id=job.job_id, result_code=int(code), error=self._last_error
            )

    def deliver(self) -> bool:
        """Tell the PLC (``last``, the result listeners) the result held until the journal
        has it; False while it is not written yet."""
        if self._held is None:
            return True
        result, durable = self._held
        if not durable.is_set():
            return False
        self._held = None
        self.last = result
        self.counters = self.journal.counters()
        self.publish()  # the snapshot a listener reads holds this result and its counters
        for listener in list(self.listeners):
            with contextlib.suppress(Exception):  # a listener must never take the cell down
                listener(result)
        return True

    def held(self) -> list[str]:
        """The results the journal has not written yet (a full disk)."""
        return self.journal.held()

    @property
    def _last_error(self) -> str:
        return str(getattr(self.journal, "last_error", ""))

    def close(self) -> None:
        self.journal.close()
