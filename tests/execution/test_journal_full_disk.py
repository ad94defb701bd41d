"""No result is lost to a full disk (a real one: a small tmpfs), and a journal that
cannot be opened says why.

The SQLite journal retries what it could not write, in order, until the space comes
back; a job's end is durable before anyone is told (its event); a new job is refused
while anything waits; close() names what it could not write."""

from __future__ import annotations

import logging
import os
import sqlite3
import subprocess
import sys
import time

import pytest

from cellrunner.errors import CellrunnerError
from cellrunner.execution.journal import JournalError, SqliteJournal
from cellrunner.model.codes import ResultCode
from tests.execution.small_disk import fill, small_disk


def _wait(event, timeout_s: float = 5.0) -> bool:
    return event.wait(timeout_s)


def test_a_result_written_on_a_full_disk_waits_and_lands_in_order(tmp_path, caplog):
    with small_disk(tmp_path, 1024) as disk:
        journal = SqliteJournal(disk / "jobs.sqlite", "c").open()
        journal.begin_job("j1", "c", "t", {"slot": 1}, "modbus", "7")
        filler = fill(disk)
        with caplog.at_level(logging.WARNING, logger="cellrunner.execution.journal"):
            for i in range(1, 41):  # enough step rows to need new pages
                journal.step("j1", i, "move", f"step {i}", "ok", 1, "x" * 200)
            durable = journal.end_job("j1", ResultCode.OK, 4.5, 0)
        assert not durable.is_set()
        assert "the result of job j1 (0 OK)" in journal.held()
        assert any("cannot be written" in r.getMessage() for r in caplog.records)
        with pytest.raises(JournalError, match="earlier writes still wait"):
            journal.begin_job("j2", "c", "t", {}, "modbus", "8")  # nothing new before them
        time.sleep(0.5)
        assert not durable.is_set() and journal.get("j1").ended_at is None
        filler.unlink()  # the space comes back
        assert _wait(durable), journal.held()
        assert journal.held() == []
        record = journal.get("j1")
        assert (record.result_code, record.cycle_time_s) == (0, 4.5)
        steps = [row[0] for row in journal.steps_of("j1")]
        assert steps == list(range(1, 41))  # every step, in order
        journal.begin_job("j2", "c", "t", {}, "modbus", "8")
        journal.close()


def test_close_names_the_results_it_could_not_write(tmp_path, caplog):
    with small_disk(tmp_path, 1024) as disk:
        journal = SqliteJournal(disk / "jobs.sqlite", "c", flush_timeout_s=0.5).open()
        journal.begin_job("j1", "c", "t", {}, "modbus", "7")
        fill(disk)
        for i in range(1, 41):
            journal.step("j1", i, "move", "m", "ok", 1, "x" * 200)
        journal.end_job("j1", ResultCode.NO_PART, 3.0, 2)
        journal.close()
    assert "the result of job j1 (1 " in journal.undelivered[-1]
    assert "could not be written" in caplog.text


def test_a_new_journal_on_a_full_disk_says_so_and_leaves_no_empty_file(tmp_path):
    with small_disk(tmp_path, 256) as disk:
        fill(disk)
        with pytest.raises(CellrunnerError, match=r"the disk is full \(0 bytes free"):
            SqliteJournal(disk / "jobs.sqlite").open()
        assert not (disk / "jobs.sqlite").exists()  # a later start is not "history lost"


def test_a_locked_journal_is_named_locked(tmp_path):
    path = tmp_path / "jobs.sqlite"
    SqliteJournal(path).open().close()
    other = sqlite3.connect(path)
    other.execute("PRAGMA journal_mode=DELETE")
    other.execute("BEGIN EXCLUSIVE")
    try:
        with pytest.raises(CellrunnerError, match="is locked by another process") as err:
            SqliteJournal(path).open()
        assert "move it away" not in str(err.value)
    finally:
        other.rollback()
        other.close()


def test_only_a_file_that_is_no_database_gets_the_advice_to_move_it(tmp_path):
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is no database" * 100)
    with pytest.raises(CellrunnerError, match=r"not a SQLite database.*move it away"):
        SqliteJournal(junk).open()
    good = tmp_path / "jobs.sqlite"
    SqliteJournal(good).open().close()
    damaged = bytearray(good.read_bytes())
    damaged[100:4000] = b"\xff" * 3900
    (tmp_path / "damaged.sqlite").write_bytes(bytes(damaged))
    with pytest.raises(CellrunnerError, match="damaged SQLite database") as err:
        SqliteJournal(tmp_path / "damaged.sqlite").open()
    assert "move it away" not in str(err.value)


NO_DAC = r"""
import ctypes, os, sys
# drop CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH, so root reads by the file's mode too
libc = ctypes.CDLL(None, use_errno=True)
class Header(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]
class Data(ctypes.Structure):
    _fields_ = [("effective", ctypes.c_uint32), ("permitted", ctypes.c_uint32),
                ("inheritable", ctypes.c_uint32)]
header, data = Header(0x20080522, 0), (Data * 2)()
if os.geteuid() == 0:
    assert libc.capget(ctypes.byref(header), data) == 0
    data[0].effective &= ~0b110
    assert libc.capset(ctypes.byref(header), data) == 0, ctypes.get_errno()
from cellrunner.execution.journal import SqliteJournal
SqliteJournal(sys.argv[1]).open()
"""


def test_an_unreadable_journal_is_named_unreadable_and_left_alone(tmp_path):
    """Mode 000 (the process, root or not, reads by the mode): permission denied, never
    "not a cellrunner journal ... move it away"."""
    path = tmp_path / "jobs.sqlite"
    journal = SqliteJournal(path).open()
    journal.begin_job("j1", "c", "t", {}, "cli")
    journal.close()
    before = path.read_bytes()
    os.chmod(path, 0)
    r = subprocess.run(
        [sys.executable, "-c", NO_DAC, str(path)], capture_output=True, text=True, timeout=60
    )
    assert r.returncode != 0
    last = r.stderr.strip().splitlines()[-1]
    assert f"cannot be opened: permission denied (owner uid {os.getuid()}, mode ----------)" in last
    assert "move it away" not in last and "not a cellrunner journal" not in last
    os.chmod(path, 0o600)
    assert path.read_bytes() == before
