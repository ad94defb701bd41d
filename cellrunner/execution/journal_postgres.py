"""The plant-wide journal: one PostgreSQL database shared by many cells (``journal:
postgresql://user@host/db``), with the SQLite journal's guarantees.

* :meth:`PostgresJournal.begin_job` returns only once the job's row is committed, or
  raises :class:`~cellrunner.execution.journal.JournalError` (the cell then rejects the
  job with 12): a job is journaled before JOB_ACK.
* Step transitions and results are queued, in order, to one writer thread, so the
  control loop never waits on the network; the writer retries through a database
  restart (reconnecting with backoff) until each write is committed. Every write is
  idempotent (``ON CONFLICT DO NOTHING`` on the job id and a per-job step sequence, an
  end that only closes an open job), so a write retried after a lost commit
  acknowledgement is never duplicated.
* While the database is away, new jobs are refused at once (nothing is acknowledged
  that is not journaled); the job under way finishes and its writes are delivered
  when the database is back. :meth:`close` waits (bounded) for the queue to drain.
* Each cell reads and closes (107 at start-up) its own jobs only; ``cell=None`` reads
  across cells.

psycopg (3) is imported only when a ``postgresql://`` journal is used.
"""

from __future__ import annotations

import contextlib
import queue
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from cellrunner.execution.journal import JobReads, JournalError, display_location
from cellrunner.execution.journal_rows import JobRecord, failure_json, record_of
from cellrunner.model.codes import ResultCode
from cellrunner.model.failure import Failure

#: serialises schema creation when several cells start at once (pg_advisory_xact_lock key)
_SCHEMA_LOCK = 0x63656C6C  # "cell"
_SCHEMA = (
    """CREATE TABLE IF NOT EXISTS cellrunner_jobs (
        seq BIGSERIAL UNIQUE,
        job_id TEXT PRIMARY KEY,
        client_job_id TEXT,
        cell TEXT NOT NULL,
        task TEXT NOT NULL,
        params JSONB NOT NULL,
        source TEXT NOT NULL,
        started_at DOUBLE PRECISION NOT NULL,
        ended_at DOUBLE PRECISION,
        result_code INTEGER,
        result_text TEXT,
        cycle_time_s DOUBLE PRECISION,
        retries INTEGER NOT NULL DEFAULT 0,
        failure TEXT)""",
    # a journal made before jobs kept their typed failure gains the column
    "ALTER TABLE cellrunner_jobs ADD COLUMN IF NOT EXISTS failure TEXT",
    """CREATE TABLE IF NOT EXISTS cellrunner_steps (
        job_id TEXT NOT NULL REFERENCES cellrunner_jobs(job_id) ON DELETE CASCADE,
        seq INTEGER NOT NULL,
        step_index INTEGER NOT NULL,
        kind TEXT NOT NULL,
        name TEXT NOT NULL,
        status TEXT NOT NULL,
        attempt INTEGER NOT NULL,
        at DOUBLE PRECISION NOT NULL,
        message TEXT,
        PRIMARY KEY (job_id, seq))""",
    "CREATE INDEX IF NOT EXISTS cellrunner_jobs_cell ON cellrunner_jobs (cell, started_at)",
    "CREATE INDEX IF NOT EXISTS cellrunner_jobs_client ON cellrunner_jobs (cell, source, client_job_id)",
    "CREATE INDEX IF NOT EXISTS cellrunner_jobs_open ON cellrunner_jobs (cell) WHERE ended_at IS NULL",
)
_COLUMNS = (
    "job_id, client_job_id, cell, task, params, source, started_at, ended_at, result_code, "
    "result_text, cycle_time_s, retries, failure"
)

#: how long begin_job waits for its commit before the job is refused, s
BEGIN_TIMEOUT_S = 3.0
#: how long close() waits for queued writes to reach the database, s
FLUSH_TIMEOUT_S = 15.0
CONNECT_TIMEOUT_S = 2
RETRY_BACKOFF_S = (0.1, 0.2, 0.5, 1.0)


@dataclass
class _Write:
    """One queued statement (``sql`` None: a marker that only reports the queue drained)."""

    sql: str | None
    args: tuple[Any, ...] = ()
    what: str = ""  # for held(): "the result of job J (0 OK)"
    done: threading.Event = field(default_factory=threading.Event)
    cancelled: bool = False
    error: str = ""


class PostgresJournal(JobReads):
    """A journal in a PostgreSQL database, for ``cell`` (None: every cell, read-only use)."""

    _ARG = "%s"
    _SEQ = "seq"

    def __init__(
        self,
        url: str,
        cell: str | None = None,
        *,
        begin_timeout_s: float = BEGIN_TIMEOUT_S,
        flush_timeout_s: float = FLUSH_TIMEOUT_S,
    ) -> None:
        self.url, self.cell = url, cell
        self.begin_timeout_s, self.flush_timeout_s = begin_timeout_s, flush_timeout_s
        self._queue: queue.Queue[_Write | None] = queue.Queue()
        self._writer: threading.Thread | None = None
        self._write_conn: Any = None
        self._read_conn: Any = None
        self._read_lock = threading.Lock()
        self._healthy = False
        self._last_error = ""
        self._abandon = threading.Event()
        self._step_seq: dict[str, int] = {}
        self._counters = [0, 0]
        self._ended: set[str] = set()
        self.undelivered = 0  # writes still queued when close() gave up

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> PostgresJournal:
        """Connect, create the tables if absent, start the writer. Raises JournalError
        when the database cannot be reached."""
        self._write_conn = self._connect()
        with self._write_conn.transaction():
            self._write_conn.execute("SELECT pg_advisory_xact_lock(%s)", (_SCHEMA_LOCK,))
            for statement in _SCHEMA:
                self._write_conn.execute(statement)
        self._healthy = True
        if self.cell is not None:
            ok, nok = self._read(
                "SELECT count(*) FILTER (WHERE result_code = 0), "
                "count(*) FILTER (WHERE result_code BETWEEN 1 AND 3) FROM cellrunner_jobs WHERE cell = %s",
                (self.cell,),
            )[0]
            self._counters = [int(ok), int(nok)]
        self._writer = threading.Thread(target=self._write_loop, name="journal-writer", daemon=True)
        self._writer.start()
        return self

    def close(self) -> None:
        """Deliver what is queued (at most ``flush_timeout_s``), then disconnect."""
        if self._writer is not None:
            self._queue.put(None)
            self._writer.join(self.flush_timeout_s)
            if self._writer.is_alive():
                self._abandon.set()
                self._writer.join(5.0)
            self.undelivered = self._queue.qsize()
            if self.undelivered:
                sys.stderr.write(
                    f"journal: {self.undelivered} writes could not reach {self._location()} "
                    f"({self._last_error})\n"
                )
            self._writer = None
        for conn in (self._write_conn, self._read_conn):
            if conn is not None:
                conn.close()
        self._write_conn = self._read_conn = None

    # ------------------------------------------------------------------ writes
    def begin_job(
        self,
        job_id: str,
        cell: str,
        task: str,
        params: dict[str, Any],
        source: str,
        client_job_id: str | None = None,
    ) -> None:
        from psycopg.types.json import Jsonb

        if not self._healthy:
            raise JournalError(
                f"journal database unreachable ({self._location()}: {self._last_error})"
            )
        self._step_seq[job_id] = 0
        item = self._enqueue(
            "INSERT INTO cellrunner_jobs (job_id, client_job_id, cell, task, params, source, started_at) "
            "VALUES (%s, %s, %s, %s, %s, %s, %s) ON CONFLICT (job_id) DO NOTHING",
            (job_id, client_job_id, cell, task, Jsonb(params), source, time.time()),
        )
        if item.done.wait(self.begin_timeout_s) and not item.error:
            return
        item.cancelled = True  # and undo it, should it land after all
        self._enqueue(
            "DELETE FROM cellrunner_jobs WHERE job_id = %s AND ended_at IS NULL", (job_id,)
        )
        raise JournalError(
            f"job {job_id} could not be journaled within {self.begin_timeout_s:g} s "
            f"({self._location()}: {item.error or self._last_error or 'no answer'})"
        )

    def step(
        self,
        job_id: str,
        index: int,
        kind: str,
        name: str,
        status: str,
        attempt: int,
        message: str = "",
    ) -> None:
        seq = self._step_seq.get(job_id, 0) + 1
        self._step_seq[job_id] = seq
        self._enqueue(
            "INSERT INTO cellrunner_steps (job_id, seq, step_index, kind, name, status, attempt, at, message) "
            "VALUES (%s, %s, %s, %s, %s, %s, %s, %s, %s) ON CONFLICT (job_id, seq) DO NOTHING",
            (job_id, seq, index, kind, name, status, attempt, time.time(), message),
        )

    def end_job(
        self,
        job_id: str,
        code: ResultCode,
        cycle_time_s: float | None,
        retries: int,
        text: str | None = None,
        failure: Failure | None = None,
    ) -> threading.Event:
        item = self._enqueue(
            "UPDATE cellrunner_jobs SET ended_at = %s, result_code = %s, result_text = %s, cycle_time_s = %s, "
            "retries = %s, failure = %s WHERE job_id = %s AND ended_at IS NULL",
            (
                time.time(),
                int(code),
                text or code.text,
                cycle_time_s,
                retries,
                failure_json(failure),
                job_id,
            ),
            f"the result of job {job_id} ({int(code)} {code.text})",
        )
        self._step_seq.pop(job_id, None)
        if job_id not in self._ended:
            self._ended.add(job_id)
            if code == ResultCode.OK:
                self._counters[0] += 1
            elif ResultCode.NO_PART <= code <= ResultCode.PLACE_FAILED:
                self._counters[1] += 1
        return item.done

    def held(self) -> list[str]:
        """The results queued and not yet committed, oldest first."""
        return [item.what for item in list(self._queue.queue) if item is not None and item.what]

    def close_interrupted(self) -> list[JobRecord]:
        """Close this cell's jobs left unfinished (a restart mid-job) with code 107."""
        open_jobs = self._select("ended_at IS NULL")
        for job in open_jobs:
            self.end_job(job.job_id, ResultCode.INTERRUPTED, None, job.retries)
        self._flush()
        closed = (self.get(job.job_id) for job in open_jobs)
        return [record for record in closed if record is not None]

    # ------------------------------------------------------------------ reads
    def counters(self) -> tuple[int, int]:
        """(parts processed, parts defective) of this cell, kept in memory (no I/O)."""
        return self._counters[0], self._counters[1]

    def steps_of(self, job_id: str) -> list[tuple[Any, ...]]:
        return self._read(
            "SELECT step_index, kind, name, status, attempt, at, message FROM cellrunner_steps "
            "WHERE job_id = %s ORDER BY seq",
            (job_id,),
        )

    # ------------------------------------------------------------------ internals
    def _jobs(self, clause: str, args: tuple[Any, ...]) -> list[JobRecord]:
        return [
            record_of(r)
            for r in self._read(f"SELECT {_COLUMNS} FROM cellrunner_jobs {clause}", args)
        ]

    def _read(self, sql: str, args: tuple[Any, ...]) -> list[tuple[Any, ...]]:
        """Run a query on the read connection, reconnecting once if it was lost."""
        import psycopg

        with self._read_lock:
            for attempt in (1, 2):
                try:
                    if self._read_conn is None or self._read_conn.closed:
                        self._read_conn = self._connect()
                    rows: list[tuple[Any, ...]] = self._read_conn.execute(sql, args).fetchall()
                    return rows
                except (psycopg.OperationalError, psycopg.InterfaceError) as exc:
                    self._drop_read()
                    if attempt == 2:
                        raise JournalError(
                            f"cannot read the journal ({self._location()}): {_first_line(exc)}"
                        ) from exc
                except JournalError:
                    self._drop_read()
                    raise
        return []

    def _drop_read(self) -> None:
        if self._read_conn is not None:
            with contextlib.suppress(Exception):
                self._read_conn.close()
        self._read_conn = None

    def _enqueue(self, sql: str | None, args: tuple[Any, ...] = (), what: str = "") -> _Write:
        if self._writer is None:
            raise JournalError("journal is not open")
        item = _Write(sql, args, what)
        self._queue.put(item)
        return item

    def _flush(self) -> None:
        """Wait until everything queued so far is committed (reads that must see it)."""
        marker = self._enqueue(None)
        if not marker.done.wait(self.begin_timeout_s):
            raise JournalError(
                f"journal database unreachable ({self._location()}: {self._last_error})"
            )

    def _write_loop(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=1.0)
            except queue.Empty:
                if not self._healthy:
                    self._probe()  # so that new jobs are accepted again once it is back
                continue
            if item is None:
                return
            self._apply(item)
            item.done.set()

    def _apply(self, item: _Write) -> None:
        """Commit ``item``, retrying through lost connections until it lands."""
        import psycopg

        failures = 0
        while item.sql is not None and not item.cancelled:
            try:
                if self._write_conn is None or self._write_conn.closed:
                    self._write_conn = self._connect()
                self._write_conn.execute(item.sql, item.args)
                self._healthy = True
                return
            except (psycopg.OperationalError, psycopg.InterfaceError, JournalError) as exc:
                self._healthy, self._last_error = False, _first_line(exc)
                self._drop_write()
                if self._abandon.is_set():
                    item.error = self._last_error
                    return
                time.sleep(RETRY_BACKOFF_S[min(failures, len(RETRY_BACKOFF_S) - 1)])
                failures += 1
            except psycopg.Error as exc:  # not a connection problem: retrying would not help
                item.error = _first_line(exc)
                sys.stderr.write(f"journal: write refused by {self._location()}: {item.error}\n")
                return

    def _probe(self) -> None:
        try:
            if self._write_conn is None or self._write_conn.closed:
                self._write_conn = self._connect()
            self._write_conn.execute("SELECT 1")
            self._healthy = True
        except Exception as exc:  # the writer thread's health probe: any failure means away
            self._last_error = _first_line(exc)
            self._drop_write()

    def _drop_write(self) -> None:
        if self._write_conn is not None:
            with contextlib.suppress(Exception):
                self._write_conn.close()
        self._write_conn = None

    def _connect(self) -> Any:
        import psycopg

        try:
            return psycopg.connect(
                self.url,
                autocommit=True,
                connect_timeout=CONNECT_TIMEOUT_S,
                application_name=f"cellrunner {self.cell or 'jobs'}"[:63],
            )
        except psycopg.Error as exc:
            raise JournalError(
                f"cannot reach the journal database {self._location()}: {_first_line(exc)}"
            ) from exc

    def _location(self) -> str:
        return display_location(self.url)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
