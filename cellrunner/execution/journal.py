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

A job the planner refused keeps its typed failure (:class:`~cellrunner.model.failure.Failure`
as JSON in ``jobs.failure``: kind, step, blockers with their distances, fix) beside its
text; a journal written before that column existed gains it when opened, its old jobs
with none.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import shutil
import sqlite3
import stat
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any, Protocol

from cellrunner.errors import CellrunnerError
from cellrunner.execution.journal_rows import JobRecord as JobRecord
from cellrunner.execution.journal_rows import failure_json, record_of
from cellrunner.model.codes import ResultCode
from cellrunner.model.failure import Failure

_log = logging.getLogger(__name__)

#: the ``journal:`` values that name a PostgreSQL database
POSTGRES_SCHEMES = ("postgresql://", "postgres://")
#: waits between tries of a write that failed (a full disk, an I/O error), s
RETRY_BACKOFF_S = (0.1, 0.2, 0.5, 1.0)
#: how long close() waits for waiting writes to land, s (a command stopped by a signal
#: waits less: ``serve`` bounds it by what is left of its grace, cli/cmd_serve.py)
FLUSH_TIMEOUT_S = 5.0

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
    retries INTEGER DEFAULT 0,
    failure TEXT
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


class _Write:
    """One statement for the journal; ``done`` is set once it is committed."""

    def __init__(self, sql: str, args: tuple[Any, ...], what: str, *, result: bool = False) -> None:
        self.sql, self.args, self.what, self.result = sql, args, what, result
        self.done = threading.Event()


class JournalError(CellrunnerError):
    """The journal cannot be written or read (database unreachable, ...): jobs are refused
    rather than run unjournaled."""

    exit_code = 3


class JournalBackend(Protocol):
    """What the cell and the status page need from a journal (SQLite or PostgreSQL).

    Construct (no I/O), :meth:`open`, use, :meth:`close`. :meth:`begin_job` is durable
    when it returns, or raises :class:`JournalError` (a job is journaled before it is
    acknowledged); later writes of a job never raise for a database that is away or a
    disk that is full: they are retried, in order, until they land. :meth:`end_job`
    returns an event set once the result is durable (a PLC is told the result only
    then); :meth:`held` names the results still waiting. ``counters`` never waits on I/O.
    """

    cell: str | None
    #: how long :meth:`close` waits for what is queued to land, s
    flush_timeout_s: float

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
        failure: Failure | None = None,
    ) -> threading.Event: ...
    def close_interrupted(self) -> list[JobRecord]: ...
    def held(self) -> list[str]: ...
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


class JobReads:
    """The reads every journal answers alike, each in its own SQL: ``_ARG`` is its
    placeholder and ``_SEQ`` the column that keeps the order jobs were written in; reads
    are narrowed to ``cell`` (None: every cell). A journal gives :meth:`_jobs`, and
    :meth:`_flush` when it queues writes."""

    _ARG = "?"
    _SEQ = "rowid"
    cell: str | None

    def _jobs(self, clause: str, args: tuple[Any, ...]) -> list[JobRecord]:
        """The jobs a ``WHERE ... [ORDER BY ...]`` clause selects."""
        raise NotImplementedError

    def _where(self, cond: str, args: tuple[Any, ...]) -> tuple[str, tuple[Any, ...]]:
        """``WHERE cond``, narrowed to this journal's cell."""
        if self.cell is None:
            return f"WHERE {cond}", args
        return f"WHERE cell = {self._ARG} AND ({cond})", (self.cell, *args)

    def _select(
        self,
        cond: str,
        args: tuple[Any, ...] = (),
        order: str = "",
        order_args: tuple[Any, ...] = (),
    ) -> list[JobRecord]:
        """This journal's jobs ``WHERE cond`` (its cell's only, when it has one)."""
        where, args = self._where(cond, args)
        return self._jobs(f"{where} {order}", (*args, *order_args))

    def _flush(self) -> None:
        """Commit what is queued before a read that must see it (no queue: nothing)."""

    def get(self, job_id: str) -> JobRecord | None:
        rows = self._select(f"job_id = {self._ARG}", (job_id,))
        return rows[0] if rows else None

    def by_client_id(self, source: str, client_job_id: str) -> JobRecord | None:
        """The first job ``source`` asked for under ``client_job_id`` (OPC UA idempotency)."""
        self._flush()
        rows = self._select(
            f"source = {self._ARG} AND client_job_id = {self._ARG}",
            (source, client_job_id),
            f"ORDER BY {self._SEQ} LIMIT 1",
        )
        return rows[0] if rows else None

    def last(self, n: int = 20) -> list[JobRecord]:
        order = f"ORDER BY started_at DESC, {self._SEQ} DESC LIMIT {self._ARG}"
        return list(reversed(self._select("1 = 1", (), order, (n,))))

    def last_finished(self) -> JobRecord | None:
        order = f"ORDER BY ended_at DESC, {self._SEQ} DESC LIMIT 1"
        rows = self._select("ended_at IS NOT NULL", (), order)
        return rows[0] if rows else None


class SqliteJournal(JobReads):
    """One SQLite file (WAL, synchronous FULL), so a crash right after a write never
    loses what it wrote. ``cell`` scopes what is read and closed to one cell (None: every
    cell in the file).

    A step or end that cannot be written (a full disk, an I/O error, a lock held too
    long) is not lost: it waits in a backlog that one writer thread retries, in order,
    until it lands (:data:`RETRY_BACKOFF_S`); writes after it join the backlog behind
    it, and a new job is refused while anything waits. :meth:`end_job`'s event is set
    once the end is committed; :meth:`close` waits :data:`FLUSH_TIMEOUT_S` for the
    backlog and names what it could not write."""

    def __init__(
        self, path: str | Path, cell: str | None = None, *, flush_timeout_s: float = FLUSH_TIMEOUT_S
    ) -> None:
        self.path = Path(path)
        self.cell = cell
        self.flush_timeout_s = flush_timeout_s
        self._db: sqlite3.Connection | None = None
        self._lock = threading.Lock()  # the control thread and the PLC threads share the connection
        self._backlog: deque[_Write] = deque()  # failed writes, oldest first
        self._wake = threading.Condition()
        self._writer: threading.Thread | None = None
        self._closing = self._abandon = False
        self.last_error = ""
        self.undelivered: list[str] = []  # what close() could not write

    def _execute(self, sql: str, args: tuple[Any, ...] = ()) -> sqlite3.Cursor:
        with self._lock:
            return self.db.execute(sql, args)

    def _fetchall(self, sql: str, args: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
        with self._lock:
            return self.db.execute(sql, args).fetchall()

    def open(self) -> SqliteJournal:
        """Open (or create, readable by its owner only) the journal. An existing file that
        is empty or not a journal is an error, never silently started afresh: that would
        lose the history, the counters and an interrupted job's 107. A journal that cannot
        be opened says why (:func:`open_problem`): permissions, a full disk, a lock."""
        on_disk = self.path != Path(":memory:")
        created = False
        try:
            if on_disk:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                if self.path.exists() and self.path.stat().st_size == 0:
                    raise CellrunnerError(
                        f"journal {self.path} is empty (0 bytes): its history is lost; restore "
                        "it from a backup, or move it away to start a new journal"
                    )
                if not self.path.exists():
                    os.close(os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
                    created = True
            self._db = sqlite3.connect(
                str(self.path), isolation_level=None, check_same_thread=False
            )
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.executescript(_SCHEMA)
            _add_failure_column(self._db)
            if on_disk:
                for path in (self.path, Path(f"{self.path}-wal"), Path(f"{self.path}-shm")):
                    if path.exists():
                        os.chmod(path, 0o600)  # job history is the line's business only
        except (sqlite3.Error, OSError) as exc:
            self.close()
            if created:  # ours and empty: a later start must not take it for lost history
                with contextlib.suppress(OSError):
                    self.path.unlink()
            raise CellrunnerError(open_problem(self.path, exc)) from exc
        return self

    def close(self) -> None:
        """Write what waits (at most ``flush_timeout_s``), then close; what could not be
        written is named on stderr and in :attr:`undelivered`."""
        writer = self._writer
        if writer is not None:
            with self._wake:
                self._closing = True
                self._wake.notify()
            writer.join(self.flush_timeout_s)
            with self._wake:
                self._abandon = True
                self._wake.notify()
            writer.join(5.0)
            self._writer = None
            self.undelivered = [item.what for item in self._backlog]
            for what in self.undelivered:
                _log.warning(
                    "journal %s: %s could not be written (%s)", self.path, what, self.last_error
                )
        if self._db is not None:
            with self._lock:
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
        if self._backlog:  # in order: nothing new is journaled before what waits
            raise JournalError(
                f"journal {self.path}: {len(self._backlog)} earlier writes still wait "
                f"({self.last_error})"
            )
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
        self._write(
            _Write(
                "INSERT INTO steps (job_id, step_index, kind, name, status, attempt, at, message) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (job_id, index, kind, name, status, attempt, time.time(), message),
                f"step {index} of job {job_id}",
            )
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
        return self._write(
            _Write(
                "UPDATE jobs SET ended_at = ?, result_code = ?, result_text = ?, cycle_time_s = ?, "
                "retries = ?, failure = ? WHERE job_id = ? AND ended_at IS NULL",
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
                result=True,
            )
        )

    def held(self) -> list[str]:
        """The results waiting to be written, oldest first (``"the result of job J (0
        OK)"``)."""
        return [item.what for item in list(self._backlog) if item.result]

    def _write(self, item: _Write) -> threading.Event:
        """Commit ``item`` now, or (something already waits, or it fails for a reason
        that may pass) put it in the backlog for the writer; its ``done`` is set once it
        is committed."""
        if not self._backlog:
            try:
                self._execute(item.sql, item.args)
                item.done.set()
                return item.done
            except sqlite3.OperationalError as exc:  # full, I/O error, locked: may pass
                self._failed(item, exc)
        with self._wake:
            self._backlog.append(item)
            if self._writer is None:
                self._writer = threading.Thread(
                    target=self._write_backlog, name="journal-writer", daemon=True
                )
                self._writer.start()
            self._wake.notify()
        return item.done

    def _write_backlog(self) -> None:
        """The writer thread: the oldest waiting write, again and again, until it lands."""
        failures = 0
        while True:
            with self._wake:
                while not self._backlog and not self._closing:
                    self._wake.wait()
                if not self._backlog:
                    return
                item = self._backlog[0]
            try:
                self._execute(item.sql, item.args)
            except sqlite3.OperationalError as exc:
                self._failed(item, exc, quiet=failures > 0)
                failures += 1
                with self._wake:
                    if self._closing and self._abandon:
                        return
                    self._wake.wait(RETRY_BACKOFF_S[min(failures, len(RETRY_BACKOFF_S)) - 1])
                continue
            except sqlite3.Error as exc:  # refused for good (a constraint): retrying won't help
                _log.error("journal %s: %s refused: %s", self.path, item.what, exc)
            if failures:
                _log.warning(
                    "journal %s: written again after %d tries: %s",
                    self.path,
                    failures + 1,
                    item.what,
                )
            failures = 0
            with self._wake:
                self._backlog.popleft()
            item.done.set()

    def _failed(self, item: _Write, exc: sqlite3.Error, *, quiet: bool = False) -> None:
        self.last_error = str(exc)
        if not quiet:
            _log.warning(
                "journal %s cannot be written (%s): %s waits and is retried",
                self.path,
                exc,
                item.what,
            )

    def close_interrupted(self) -> list[JobRecord]:
        """Close every job of this cell left unfinished (a restart mid-job) with code 107."""
        open_jobs = self._select("ended_at IS NULL")
        for job in open_jobs:
            self.end_job(job.job_id, ResultCode.INTERRUPTED, None, job.retries)
        closed = (self.get(job.job_id) for job in open_jobs)
        return [record for record in closed if record is not None]

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

    def _jobs(self, clause: str, args: tuple[Any, ...]) -> list[JobRecord]:
        rows = self._fetchall(
            "SELECT job_id, client_job_id, cell, task, params, source, started_at, ended_at, result_code, "
            f"result_text, cycle_time_s, retries, failure FROM jobs {clause}",
            args,
        )
        return [record_of(r) for r in rows]


def _add_failure_column(db: sqlite3.Connection) -> None:
    """A journal written before jobs had a ``failure`` column gains it (its old jobs
    read with none)."""
    columns = {row[1] for row in db.execute("PRAGMA table_info(jobs)")}
    if "failure" not in columns:
        db.execute("ALTER TABLE jobs ADD COLUMN failure TEXT")


_SQLITE_MAGIC = b"SQLite format 3\x00"


def open_problem(path: Path, exc: sqlite3.Error | OSError) -> str:
    """Why the SQLite journal at ``path`` could not be opened, from what is on disk: the
    advice to move a file away is given only for a file that is not a SQLite database."""
    reason = str(exc) if isinstance(exc, sqlite3.Error) else (exc.strerror or str(exc))
    where = f"journal {path}"
    try:
        with open(path, "rb") as file:
            head = file.read(len(_SQLITE_MAGIC))
    except PermissionError:
        return (
            f"{where} cannot be opened: permission denied ({_owner_and_mode(path)}); let "
            f"the user running cellrunner (uid {os.getuid()}) read and write it"
        )
    except FileNotFoundError:
        head = None
    except OSError as err:
        return f"{where} cannot be read: {err.strerror or err}"
    lowered = reason.lower()
    if (isinstance(exc, OSError) and exc.errno == errno.ENOSPC) or "full" in lowered:
        free = _free_bytes(path)
        return (
            f"{where} cannot be written: the disk is full ({free} bytes free on its "
            "file system); free some space; the journal itself is intact"
        )
    if "locked" in lowered or "busy" in lowered:
        return (
            f"{where} is locked by another process (another cellrunner serving this "
            "cell?); stop it, or give this cell its own journal: file"
        )
    if "readonly" in lowered or "read-only" in lowered or isinstance(exc, PermissionError):
        return (
            f"{where} cannot be written ({reason}): its folder {path.parent} must be "
            f"writable too, for SQLite's -wal and -shm files ({_owner_and_mode(path.parent)})"
        )
    if head is not None and head != _SQLITE_MAGIC and head:
        return (
            f"{where} is not a cellrunner journal (not a SQLite database: {reason}); "
            "restore it from a backup, or move it away to start a new journal"
        )
    if "malformed" in lowered or "not a database" in lowered:
        return (
            f"{where} is a damaged SQLite database ({reason}); keep it, and restore the "
            "journal from a backup (sqlite3 .recover can save what is left)"
        )
    return f"{where} cannot be opened: {reason}"


def _owner_and_mode(path: Path) -> str:
    try:
        st = path.stat()
    except OSError:
        return "not readable"
    return f"owner uid {st.st_uid}, mode {stat.filemode(st.st_mode)}"


def _free_bytes(path: Path) -> int:
    try:
        return shutil.disk_usage(path.parent).free
    except OSError:
        return 0


#: the SQLite journal was the only one; the name stays for callers that mean a file
Journal = SqliteJournal
