"""The job journal (SPEC section 9): written before a job is acknowledged and at every
step transition after it, so no result is ever lost.

Two backends behind one :class:`JournalBackend` Protocol, picked by the cell file's
``journal:`` (:func:`~cellrunner.execution.journal_open.journal_for`): a SQLite file (the default, :class:`SqliteJournal`)
or a ``postgresql://`` URL, one database shared by many cells
(:class:`~cellrunner.execution.journal_postgres.PostgresJournal`). A journal opened for
a cell sees that cell's jobs only (several cells may share one journal); one opened
with ``cell=None`` reads across cells (``cellrunner jobs --all-cells``).

A job found unfinished at start-up is closed with result 107 by
:meth:`JournalBackend.close_interrupted` and reported as the last result.
"""

from __future__ import annotations

import json
import os
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from cellrunner.errors import CellrunnerError
from cellrunner.model.codes import ResultCode

#: the ``journal:`` values that name a PostgreSQL database
POSTGRES_SCHEMES = ("postgresql://", "postgres://")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    job_id TEXT PRIMARY KEY,
    client_job_id TEXT,
    cell TEXT NOT NULL,
    task TEXT NOT NULL,
    params TEXT NOT NULL,
    source TEXT NOT NULL,
    started_at REAL NOT NULL,
    ended_at REAL,
    result_code INTEGER,
    result_text TEXT,
    cycle_time_s REAL,
    retries INTEGER DEFAULT 0
);
CREATE TABLE IF NOT EXISTS steps (
    job_id TEXT NOT NULL REFERENCES jobs(job_id),
    step_index INTEGER NOT NULL,
    kind TEXT NOT NULL,
    name TEXT NOT NULL,
    status TEXT NOT NULL,
    attempt INTEGER NOT NULL,
    at REAL NOT NULL,
    message TEXT
);
CREATE INDEX IF NOT EXISTS steps_job ON steps(job_id);
CREATE INDEX IF NOT EXISTS jobs_client ON jobs(source, client_job_id);
"""


@dataclass(frozen=True)
class JobRecord:
    job_id: str
    client_job_id: str | None
    cell: str
    task: str
    params: dict[str, Any]
    source: str
    started_at: float
    ended_at: float | None
    result_code: int | None
    result_text: str | None
    cycle_time_s: float | None
    retries: int


class JournalError(CellrunnerError):
    """The journal cannot be written or read (database unreachable, ...): jobs are refused
    rather than run unjournaled."""

    exit_code = 3


class JournalBackend(Protocol):
    """What the cell and the status page need from a journal (SQLite or PostgreSQL).

    Construct (no I/O), :meth:`open`, use, :meth:`close`. :meth:`begin_job` is durable
    when it returns, or raises :class:`JournalError` (a job is journaled before it is
    acknowledged); later writes of a job are durable when they return, or delivered in
    order as soon as the database is back (PostgreSQL). ``counters`` never waits on I/O.
    """

    cell: str | None

    def open(self) -> JournalBackend: ...
    def close(self) -> None: ...
    def begin_job(
        self,
        job_id: str,
        cell: str,
        task: str,
        params: dict[str, Any],
        source: str,
        client_job_id: str | None = None,
    ) -> None: ...
    def step(
        self,
        job_id: str,
        index: int,
        kind: str,
        name: str,
        status: str,
        attempt: int,
        message: str = "",
    ) -> None: ...
    def end_job(
        self,
        job_id: str,
        code: ResultCode,
        cycle_time_s: float | None,
        retries: int,
        text: str | None = None,
    ) -> None: ...
    def close_interrupted(self) -> list[JobRecord]: ...
    def get(self, job_id: str) -> JobRecord | None: ...
    def by_client_id(self, source: str, client_job_id: str) -> JobRecord | None: ...
    def last(self, n: int = 20) -> list[JobRecord]: ...
    def last_finished(self) -> JobRecord | None: ...
    def counters(self) -> tuple[int, int]: ...
    def steps_of(self, job_id: str) -> list[tuple[Any, ...]]: ...


def is_database_url(location: str) -> bool:
    return location.startswith(POSTGRES_SCHEMES)


def display_location(location: str) -> str:
    """A journal location fit for messages: a database URL loses its password."""
    if not is_database_url(location):
        return location
    from urllib.parse import urlsplit

    parts = urlsplit(location)
    user = f"{parts.username}@" if parts.username else ""
    port = f":{parts.port}" if parts.port else ""
    return f"{parts.scheme}://{user}{parts.hostname or 'localhost'}{port}{parts.path}"


class SqliteJournal:
    """One SQLite file; every write is committed before the call returns (WAL, synchronous
    FULL), so a crash right after a call never loses what it wrote. ``cell`` scopes
    what is read and closed to one cell (None: every cell in the file)."""

    def __init__(self, path: str | Path, cell: str | None = None) -> None:
        self.path = Path(path)
        self.cell = cell
        self._db: sqlite3.Connection | None = None
        self._lock = threading.Lock()  # the control thread and the PLC threads share the connection

    def _execute(self, sql: str, args: tuple[Any, ...] = ()) -> sqlite3.Cursor:
        with self._lock:
            return self.db.execute(sql, args)

    def _fetchall(self, sql: str, args: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
        with self._lock:
            return self.db.execute(sql, args).fetchall()

    def open(self) -> SqliteJournal:
        """Open (or create, readable by its owner only) the journal. An existing file that
        is empty or not a journal is an error, never silently started afresh: that would
        lose the history, the counters and an interrupted job's 107."""
        on_disk = self.path != Path(":memory:")
        if on_disk:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.path.exists() and self.path.stat().st_size == 0:
                raise CellrunnerError(
                    f"journal {self.path} is empty (0 bytes): its history is lost; restore it "
                    "from a backup, or move it away to start a new journal"
                )
            if not self.path.exists():
                os.close(os.open(self.path, os.O_CREAT | os.O_WRONLY, 0o600))
        try:
            self._db = sqlite3.connect(
                str(self.path), isolation_level=None, check_same_thread=False
            )
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.executescript(_SCHEMA)
        except sqlite3.DatabaseError as exc:
            self.close()
            raise CellrunnerError(
                f"journal {self.path} is not a cellrunner journal ({exc}); restore it from a "
                "backup, or move it away to start a new journal"
            ) from exc
        if on_disk:
            for path in (self.path, Path(f"{self.path}-wal"), Path(f"{self.path}-shm")):
                if path.exists():
                    os.chmod(path, 0o600)  # job history is the line's business only
        return self

    def close(self) -> None:
        if self._db is not None:
            self._db.close()
            self._db = None

    @property
    def db(self) -> sqlite3.Connection:
        if self._db is None:
            raise RuntimeError("journal is not open")
        return self._db

    def begin_job(
        self,
        job_id: str,
        cell: str,
        task: str,
        params: dict[str, Any],
        source: str,
        client_job_id: str | None = None,
    ) -> None:
        self._execute(
            "INSERT INTO jobs (job_id, client_job_id, cell, task, params, source, started_at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (
                job_id,
                client_job_id,
                cell,
                task,
                json.dumps(params, sort_keys=True),
                source,
                time.time(),
            ),
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
        self._execute(
            "INSERT INTO steps (job_id, step_index, kind, name, status, attempt, at, message) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (job_id, index, kind, name, status, attempt, time.time(), message),
        )

    def end_job(
        self,
        job_id: str,
        code: ResultCode,
        cycle_time_s: float | None,
        retries: int,
        text: str | None = None,
    ) -> None:
        self._execute(
            "UPDATE jobs SET ended_at = ?, result_code = ?, result_text = ?, cycle_time_s = ?, retries = ? "
            "WHERE job_id = ? AND ended_at IS NULL",
            (time.time(), int(code), text or code.text, cycle_time_s, retries, job_id),
        )

    def close_interrupted(self) -> list[JobRecord]:
        """Close every job of this cell left unfinished (a restart mid-job) with code 107."""
        open_jobs = self._select("ended_at IS NULL")
        for job in open_jobs:
            self.end_job(job.job_id, ResultCode.INTERRUPTED, None, job.retries)
        closed = (self.get(job.job_id) for job in open_jobs)
        return [record for record in closed if record is not None]

    def get(self, job_id: str) -> JobRecord | None:
        rows = self._select("job_id = ?", (job_id,))
        return rows[0] if rows else None

    def by_client_id(self, source: str, client_job_id: str) -> JobRecord | None:
        """The first job ``source`` asked for under ``client_job_id`` (OPC UA idempotency)."""
        rows = self._select(
            "source = ? AND client_job_id = ?", (source, client_job_id), "ORDER BY rowid LIMIT 1"
        )
        return rows[0] if rows else None

    def last(self, n: int = 20) -> list[JobRecord]:
        return list(
            reversed(self._select("1", (), "ORDER BY started_at DESC, rowid DESC LIMIT ?", (n,)))
        )

    def last_finished(self) -> JobRecord | None:
        rows = self._select(
            "ended_at IS NOT NULL", (), "ORDER BY ended_at DESC, rowid DESC LIMIT 1"
        )
        return rows[0] if rows else None

    def counters(self) -> tuple[int, int]:
        """(parts processed, parts defective): OK jobs, and jobs that ended NOK (1-3)."""
        where, args = self._where("1", ())
        ((ok, nok),) = self._fetchall(
            f"SELECT SUM(result_code = 0), SUM(result_code BETWEEN 1 AND 3) FROM jobs {where}", args
        )
        return int(ok or 0), int(nok or 0)

    def steps_of(self, job_id: str) -> list[tuple[Any, ...]]:
        return self._fetchall(
            "SELECT step_index, kind, name, status, attempt, at, message FROM steps WHERE job_id = ? "
            "ORDER BY rowid",
            (job_id,),
        )

    def _where(self, cond: str, args: tuple[Any, ...]) -> tuple[str, tuple[Any, ...]]:
        """``WHERE cond``, narrowed to this journal's cell."""
        if self.cell is None:
            return f"WHERE {cond}", args
        return f"WHERE cell = ? AND ({cond})", (self.cell, *args)

    def _select(
        self,
        cond: str,
        args: tuple[Any, ...] = (),
        order: str = "",
        order_args: tuple[Any, ...] = (),
    ) -> list[JobRecord]:
        where, args = self._where(cond, args)
        rows = self._fetchall(
            "SELECT job_id, client_job_id, cell, task, params, source, started_at, ended_at, result_code, "
            f"result_text, cycle_time_s, retries FROM jobs {where} {order}",
            (*args, *order_args),
        )
        return [JobRecord(r[0], r[1], r[2], r[3], json.loads(r[4]), *r[5:]) for r in rows]


#: the SQLite journal was the only one; the name stays for callers that mean a file
Journal = SqliteJournal
