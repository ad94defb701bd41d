"""Holds say who held (issue 37): the PLC's Hold, its watchdog, an operator over OPC UA and
a protective stop each give their own source and reason in the log's ``hold`` event, the
journal's held row and the status (the status page and OPC UA publish the status's
``hold_source`` and ``hold_reason``)."""

from __future__ import annotations

import pytest

from cellrunner.execution.cell import CellController
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.hold_source import HoldSource
from cellrunner.web.alarms import active_alarms
from tests.execution.fakes import ScriptedArm, tick
from tests.execution.held import held_cell


def tick_until_held(cell: CellController) -> None:
    for _ in range(5000):
        tick(cell)
        if cell.status().state == S.HELD:
            return
    raise AssertionError(f"not held: {cell.status().state_name}")


REASONS = {
    HoldSource.PLC: "hold requested",  # the words the log always had
    HoldSource.PLC_WATCHDOG: "PLC watchdog: the heartbeat stopped",
    HoldSource.OPCUA: "hold requested over OPC UA",
}


@pytest.mark.parametrize("source", list(REASONS))
def test_a_requested_hold_names_its_source_in_log_journal_status_and_alarm(tmp_path, source):
    cell, log, job_id = held_cell(tmp_path, ScriptedArm())
    tick(cell, 200)
    assert cell.status().state == S.EXECUTE and cell.status().hold_source == ""
    assert cell.command("hold", source)
    tick_until_held(cell)
    holds = [fields for event, fields in log.events if event == "hold"]
    assert len(holds) == 1
    assert (holds[0]["reason"], holds[0]["source"]) == (REASONS[source], source.value)
    status = cell.status()
    assert (status.hold_source, status.hold_reason) == (source.value, REASONS[source])
    held_rows = [row for row in cell.journal.steps_of(job_id) if row[3] == "held"]
    assert len(held_rows) == 1, cell.journal.steps_of(job_id)
    assert held_rows[0][-1] == f"{source.value}: {REASONS[source]}"
    [alarm] = [a for a in active_alarms(status, {}) if "held" in a.detail]
    assert alarm.detail == f"The running job is held by {source.value}: {REASONS[source]}."
    assert cell.command("unhold")
    tick(cell, 3)
    assert cell.status().hold_source == ""  # the hold is over


def test_a_protective_stop_holds_as_protective_stop(tmp_path):
    cell, log, job_id = held_cell(tmp_path, ScriptedArm(protective_stop_at_s=0.1))
    tick_until_held(cell)
    holds = [fields for event, fields in log.events if event == "hold"]
    assert [(h["reason"], h["source"]) for h in holds] == [("protective stop", "protective_stop")]
    assert cell.status().hold_source == "protective_stop"
    held_rows = [row for row in cell.journal.steps_of(job_id) if row[3] == "held"]
    assert [row[-1] for row in held_rows] == ["protective_stop: protective stop"]


def test_every_source_has_its_own_words_and_unknown_names_list_the_known():
    reasons = [s.reason for s in HoldSource]
    assert len(set(reasons)) == len(reasons)
    assert HoldSource.named("plc_watchdog") is HoldSource.PLC_WATCHDOG
    with pytest.raises(ValueError, match="unknown hold source 'dog'; known: plc, plc_watchdog"):
        HoldSource.named("dog")
