"""The PostgreSQL journal against a real server (a throwaway cluster on loopback): the
SQLite journal's guarantees, cells sharing one database, and writes that survive a
server restart without being lost or duplicated."""

from __future__ import annotations

import time

import pytest

from cellrunner.execution.journal import JournalError, SqliteJournal
from cellrunner.execution.journal_open import journal_for
from cellrunner.execution.journal_postgres import PostgresJournal
from cellrunner.model.codes import ResultCode
from tests.execution.pg_server import PgServer

HOST = "127.0.0.142"


@pytest.fixture(scope="module")
def pg():
    with PgServer(HOST) as server:
        yield server


@pytest.fixture
def clean(pg):
    pg.sql("DROP TABLE IF EXISTS cellrunner_steps, cellrunner_jobs")
    return pg


def test_the_journal_kind_follows_the_location(tmp_path):
    assert isinstance(journal_for("postgresql://u@127.0.0.1/db", "c"), PostgresJournal)
    assert isinstance(journal_for("var/jobs.sqlite", "c", lambda p: tmp_path / p), SqliteJournal)


def test_jobs_steps_and_results_per_cell(clean):
    a = PostgresJournal(clean.url, "cell-a").open()
    b = PostgresJournal(clean.url, "cell-b").open()
    try:
        a.begin_job("a1", "cell-a", "pick", {"slot": 3}, "modbus", "17")
        a.step("a1", 1, "move", "home", "running", 1)
        a.step("a1", 1, "move", "home", "ok", 1)
        a.end_job("a1", ResultCode.OK, 6.5, 0)
        a.begin_job("a2", "cell-a", "pick", {"slot": 4}, "modbus", "18")  # left running
        b.begin_job("b1", "cell-b", "pick", {}, "opcua", "X")
        b.end_job("b1", ResultCode.NO_PART, 3.0, 2)
        assert a.counters() == (1, 0) and b.counters() == (0, 1)
        assert b.by_client_id("opcua", "X").job_id == "b1" and a.by_client_id("opcua", "X") is None
        assert [r.job_id for r in a.last(10)] == ["a1", "a2"]
        record = a.get("a1")
        assert (record.params, record.result_code, record.cycle_time_s, record.client_job_id) == (
            {"slot": 3},
            0,
            6.5,
            "17",
        )
        assert [(s[0], s[3]) for s in a.steps_of("a1")] == [(1, "running"), (1, "ok")]
        assert b.last_finished().job_id == "b1"
    finally:
        a.close()
        b.close()
    # a restart of cell-b closes nothing of cell-a's; cell-a's restart closes its own
    b = PostgresJournal(clean.url, "cell-b").open()
    assert b.close_interrupted() == []
    b.close()
    a = PostgresJournal(clean.url, "cell-a").open()
    closed = a.close_interrupted()
    assert [(r.job_id, r.result_code) for r in closed] == [("a2", 107)]
    assert a.counters() == (1, 0)
    a.close()
    everyone = PostgresJournal(clean.url, None).open()
    assert sorted((r.cell, r.job_id) for r in everyone.last(10)) == [
        ("cell-a", "a1"),
        ("cell-a", "a2"),
        ("cell-b", "b1"),
    ]
    everyone.close()


def test_writes_survive_a_server_restart_exactly_once(clean):
    journal = PostgresJournal(clean.url, "cell-a", begin_timeout_s=1.0).open()
    try:
        journal.begin_job("j1", "cell-a", "pick", {}, "modbus", "1")
        journal.step("j1", 1, "move", "home", "running", 1)
        clean.stop("immediate")  # the database crashes mid-job
        t0 = time.monotonic()
        for index in range(2, 12):  # the job goes on: its writes queue, the caller never waits
            journal.step("j1", index, "linear", f"s{index}", "running", 1)
        journal.end_job("j1", ResultCode.OK, 4.2, 0)
        assert time.monotonic() - t0 < 0.1
        with pytest.raises(JournalError, match=r"could not be journaled|unreachable"):
            journal.begin_job(
                "j2", "cell-a", "pick", {}, "modbus", "2"
            )  # nothing unjournaled is accepted
        t0 = time.monotonic()
        with pytest.raises(JournalError, match="unreachable"):
            journal.begin_job("j3", "cell-a", "pick", {}, "modbus", "3")
        assert time.monotonic() - t0 < 0.1  # refused at once while the database is away
        clean.start()
        deadline = time.monotonic() + 30
        while True:
            try:
                journal.begin_job("j4", "cell-a", "pick", {}, "modbus", "4")
                break
            except JournalError:
                assert time.monotonic() < deadline, "the journal did not come back"
                time.sleep(0.2)
        journal.end_job("j4", ResultCode.OK, 1.0, 0)
    finally:
        journal.close()
    assert journal.undelivered == 0
    rows = clean.sql("SELECT job_id, result_code FROM cellrunner_jobs ORDER BY seq")
    assert rows == [("j1", 0), ("j4", 0)]  # the refused jobs left nothing behind
    steps = clean.sql("SELECT step_index FROM cellrunner_steps WHERE job_id = 'j1' ORDER BY seq")
    assert [s[0] for s in steps] == list(range(1, 12))  # every step once, in order


def test_an_unreachable_database_is_a_clear_error(pg):
    journal = PostgresJournal(f"postgresql://cellrunner:secret@{HOST}:1/plant", "cell-a")
    with pytest.raises(JournalError) as exc:
        journal.open()
    text = str(exc.value)
    assert text.startswith(
        f"cannot reach the journal database postgresql://cellrunner@{HOST}:1/plant: "
    )
    assert "secret" not in text and exc.value.exit_code == 3


def test_jobs_command_on_an_unreachable_database_is_exit_3(tmp_path, capsys):
    from cellrunner.cli.main import main
    from tests.rig import CELL

    (tmp_path / "cells").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(CELL + f"journal: postgresql://cellrunner:secret@{HOST}:1/plant\n")
    assert main(["jobs", str(cell), "--all-cells"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"cellrunner jobs: error: cannot reach the journal database postgresql://cellrunner@{HOST}:1/plant: "
    )


def test_a_refused_jobs_failure_survives_and_an_old_table_gains_its_column(clean):
    from tests.execution.refusal import REFUSAL

    clean.sql(  # the jobs table as a journal made before the failure column wrote it
        "CREATE TABLE cellrunner_jobs (seq BIGSERIAL UNIQUE, job_id TEXT PRIMARY KEY, "
        "client_job_id TEXT, cell TEXT NOT NULL, task TEXT NOT NULL, params JSONB NOT NULL, "
        "source TEXT NOT NULL, started_at DOUBLE PRECISION NOT NULL, ended_at DOUBLE PRECISION, "
        "result_code INTEGER, result_text TEXT, cycle_time_s DOUBLE PRECISION, "
        "retries INTEGER NOT NULL DEFAULT 0)"
    )
    clean.sql(
        "INSERT INTO cellrunner_jobs (job_id, cell, task, params, source, started_at, ended_at, "
        "result_code, result_text) VALUES ('old', 'c', 't', '{}', 'cli', 1, 2, 0, 'OK')"
    )
    journal = PostgresJournal(clean.url, "c").open()
    try:
        assert journal.get("old").failure is None and journal.get("old").result_text == "OK"
        journal.begin_job("bad", "c", "t", {}, "modbus", "5")
        done = journal.end_job("bad", ResultCode.PLANNING_FAILED, 0.0, 0, REFUSAL.text(), REFUSAL)
        assert done.wait(10)
        record = journal.get("bad")
        assert record.failure == REFUSAL and record.result_text == REFUSAL.text()
    finally:
        journal.close()
