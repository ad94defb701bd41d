"""A job the planner refuses keeps its typed failure to the end: the journal stores its
kind, step, blockers (names and distances) and fix beside the text, and what reads the
journal shows them (`cellrunner jobs`, the status page's last results, OPC UA's
``Cell.LastJob``). A journal written before the failure column still loads."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
import urllib.request

from cellrunner.errors import InfeasibleError
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.model.codes import ResultCode
from cellrunner.model.failure import Failure
from cellrunner.model.load import load_cell, load_task
from cellrunner.plc.fake import FakeCell
from cellrunner.plc.opcua_address_space import last_job_values
from cellrunner.web.board import StatusBoard
from cellrunner.web.server import StatusServer
from tests.conftest import DEMO_CELL
from tests.execution.fakes import ScriptedArm, tick
from tests.execution.refusal import REFUSAL
from tests.rig import ENV, cli

#: the jobs table as journals wrote it before jobs had a failure column
OLD_SCHEMA = """
CREATE TABLE jobs (
    job_id TEXT PRIMARY KEY, client_job_id TEXT, cell TEXT NOT NULL, task TEXT NOT NULL,
    params TEXT NOT NULL, source TEXT NOT NULL, started_at REAL NOT NULL, ended_at REAL,
    result_code INTEGER, result_text TEXT, cycle_time_s REAL, retries INTEGER DEFAULT 0
);
CREATE TABLE steps (
    job_id TEXT NOT NULL REFERENCES jobs(job_id), step_index INTEGER NOT NULL,
    kind TEXT NOT NULL, name TEXT NOT NULL, status TEXT NOT NULL, attempt INTEGER NOT NULL,
    at REAL NOT NULL, message TEXT
);
INSERT INTO jobs VALUES ('old-1', '7', 'c', 'pick_place', '{"slot": 2}', 'modbus',
    1700000000.0, 1700000004.0, 103, 'step 2 approach: out of reach', 4.0, 0);
"""


def refusing_planner(loaded, params, q_now):
    raise InfeasibleError(REFUSAL)


def test_a_refused_job_is_journaled_and_told_with_its_typed_failure(tmp_path):
    cell = load_cell(DEMO_CELL)
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    journal = Journal(tmp_path / "jobs.sqlite")
    controller = CellController(cell, tasks, ScriptedArm(), journal, refusing_planner)
    controller.setup()
    try:
        tick(controller, 2)
        ticket = controller.start_job(1, {}, "9", "modbus")
        assert ticket.reject_code is None or ticket.reject_code == 0, ticket.message
        for _ in range(2000):  # planning runs on a worker thread: bounded in ticks
            tick(controller)
            if controller.status().last_result is not None:
                break
        result = controller.status().last_result
        assert result is not None and result.result_code is ResultCode.PLANNING_FAILED
        assert result.failure == REFUSAL and result.result_text == REFUSAL.text()
        record = journal.last_finished()
        assert record is not None and record.failure == REFUSAL
        assert record.result_text == REFUSAL.text()
        wire = last_job_values(result)
        assert wire["LastJob.FailureKind"] == "collision" and wire["LastJob.FailureStep"] == 3
    finally:
        controller.close()


def test_a_job_that_ends_otherwise_has_no_failure(tmp_path):
    journal = Journal(tmp_path / "jobs.sqlite").open()
    journal.begin_job("a", "c", "t", {}, "cli")
    journal.end_job("a", ResultCode.NO_PART, 1.0, 0, "no part").wait(5)
    record = journal.get("a")
    assert (
        record is not None
        and record.failure is None
        and record.result_code == int(ResultCode.NO_PART)
    )
    assert last_job_values_of(record)["LastJob.FailureKind"] == ""
    journal.close()


def last_job_values_of(record):
    from cellrunner.execution.job_view import result_of_record

    return last_job_values(result_of_record(record))


def test_an_old_journal_loads_and_gains_the_failure_column(tmp_path):
    path = tmp_path / "jobs.sqlite"
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    db.commit()
    db.close()
    journal = Journal(path, "c").open()
    try:
        old = journal.get("old-1")
        assert old is not None and old.failure is None
        assert (old.result_code, old.result_text, old.params) == (
            103,
            "step 2 approach: out of reach",
            {"slot": 2},
        )
        journal.begin_job("new-1", "c", "pick_place", {}, "cli")
        assert journal.end_job("new-1", ResultCode.PLANNING_FAILED, 0.0, 0, None, REFUSAL).wait(5)
        assert journal.get("new-1").failure == REFUSAL  # type: ignore[union-attr]
        assert [r.job_id for r in journal.last(5)] == ["old-1", "new-1"]
    finally:
        journal.close()


def test_a_failure_column_another_version_wrote_is_left_unread(tmp_path):
    journal = Journal(tmp_path / "jobs.sqlite", "c").open()
    journal.begin_job("a", "c", "t", {}, "cli")
    journal.end_job("a", ResultCode.PLANNING_FAILED, 0.0, 0, "refused").wait(5)
    journal.db.execute("UPDATE jobs SET failure = ? WHERE job_id = 'a'", ('{"kind": "new"}',))
    record = journal.get("a")
    assert record is not None and record.failure is None and record.result_text == "refused"
    journal.close()


def journal_with_refusal(tmp_path):
    """A cell file whose journal holds one refused job and one good one: its path."""
    cell = tmp_path / "c.yaml"
    cell.write_text(
        "cell: c\nrobot: {model: ur5e, home: [0, -90, 90, -90, -90, 0]}\njournal: jobs.sqlite\n"
    )
    journal = Journal(tmp_path / "jobs.sqlite", "c").open()
    journal.begin_job("bad-1", "c", "pick_place", {"slot": 3}, "modbus", "11")
    journal.end_job("bad-1", ResultCode.PLANNING_FAILED, 0.0, 0, REFUSAL.text(), REFUSAL).wait(5)
    journal.begin_job("good-1", "c", "pick_place", {"slot": 1}, "modbus", "12")
    journal.end_job("good-1", ResultCode.OK, 4.2, 0).wait(5)
    journal.close()
    return cell


def test_jobs_lists_the_failure_kind_step_and_blockers(tmp_path):
    cell = journal_with_refusal(tmp_path)
    r = cli("jobs", str(cell), "--csv")
    assert r.returncode == 0, r.stderr
    bad, good = list(csv.DictReader(io.StringIO(r.stdout)))
    assert (bad["failure_kind"], bad["failure_step"]) == ("collision", "3")
    assert bad["blockers"] == "fixture 'table' -4.0 mm, wrist_3"
    assert bad["result_text"] == REFUSAL.text()
    assert (good["failure_kind"], good["failure_step"], good["blockers"]) == ("", "", "")
    r = cli("jobs", str(cell), env={**ENV, "COLUMNS": "400"})
    assert r.returncode == 0, r.stderr
    table = r.stdout + r.stderr  # the console the table is printed on
    assert "collision at step 3: fixture 'table' -4.0 mm, wrist_3" in table


def test_the_status_page_shows_the_last_results_failure(tmp_path):
    journal_with_refusal(tmp_path)
    with FakeCell(results=[0]) as cell:
        board = StatusBoard(cell, Journal(tmp_path / "jobs.sqlite"), "c", max_age_s=0.0).setup()
        server = StatusServer(board, "127.0.0.141", 0)
        server.start()
        try:
            with urllib.request.urlopen(server.url + "status.json", timeout=5) as res:
                status = json.loads(res.read())
        finally:
            server.stop()
            board.close()
    good, bad = status["last_results"]  # newest first
    assert bad["job_id"] == "bad-1" and Failure.from_json(bad["failure"]) == REFUSAL
    assert bad["failure_brief"] == "collision at step 3: fixture 'table' -4.0 mm, wrist_3"
    assert good["failure"] is None and good["failure_brief"] == ""
