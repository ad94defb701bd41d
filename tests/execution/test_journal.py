"""The journal refuses to lose history: an empty or corrupt file is an error, a full disk
refuses the job (it is never run unjournaled), and the file is its owner's only."""

from __future__ import annotations

import sqlite3
import stat

import pytest

from cellrunner.errors import CellrunnerError
from cellrunner.execution.journal import Journal
from cellrunner.model.codes import ResultCode
from tests.execution.fakes import make_cell, tick


def test_an_empty_journal_file_is_an_error_not_a_fresh_start(tmp_path):
    path = tmp_path / "jobs.sqlite"
    path.write_bytes(b"")
    with pytest.raises(CellrunnerError, match=r"jobs.sqlite is empty \(0 bytes\)"):
        Journal(path).open()
    assert path.stat().st_size == 0  # left as found


def test_a_corrupt_journal_file_is_an_error(tmp_path):
    path = tmp_path / "jobs.sqlite"
    path.write_bytes(b"this is no database" * 100)
    with pytest.raises(CellrunnerError, match="is not a cellrunner journal"):
        Journal(path).open()


def test_the_journal_is_readable_by_its_owner_only(tmp_path):
    journal = Journal(tmp_path / "jobs.sqlite").open()
    journal.begin_job("a", "c", "t", {}, "cli")
    for path in tmp_path.iterdir():
        assert stat.S_IMODE(path.stat().st_mode) & 0o077 == 0, path
    journal.close()


def test_a_full_disk_refuses_the_job_and_serve_goes_on(tmp_path):
    """SQLite's own 'database or disk is full' (max_page_count reached): the job is
    refused with 12 before anything moves, and the controller keeps ticking."""
    cell, _ = make_cell(tmp_path)
    pages = cell.journal.db.execute("PRAGMA page_count").fetchone()[0]
    cell.journal.db.execute(f"PRAGMA max_page_count = {pages}")
    with pytest.raises(sqlite3.OperationalError, match="full"):  # fill every page's last byte
        for i in range(100_000):
            cell.journal.db.execute(
                "INSERT INTO jobs (job_id, cell, task, params, source, started_at) "
                "VALUES (?, 'c', 't', '{}', 'filler', 0)",
                (f"f{i}",),
            )
    ticket = cell.start_job(1, {}, "9", "modbus")
    assert ticket.reject_code == ResultCode.REJECT_NOT_READY and "journal" in ticket.message
    tick(cell, 5)
    assert cell.status().ready
