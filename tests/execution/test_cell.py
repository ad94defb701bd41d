"""The cell controller: PackML path of a job, rejects, journal, restart, e-stop recovery."""

from __future__ import annotations

import time

import pytest

from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from tests.execution.fakes import ScriptedArm, make_cell, tick


def test_job_goes_through_packml_and_is_journaled(tmp_path):
    cell, _arm = make_cell(tmp_path)
    assert cell.status().state == S.IDLE and cell.status().ready
    results = []
    cell.add_result_listener(results.append)
    ticket = cell.start_job(1, {"slot": 3}, "17", "modbus")
    assert ticket.accepted and cell.status().state == S.STARTING and cell.status().busy
    assert cell.journal.get(ticket.job_id).params == {"slot": 3}  # written before the ack returns
    seen = set()
    tick(cell)  # the control thread starts planning: wait for it, not for a count of ticks
    assert cell.wait_for_plan(timeout_s=120)
    for _ in range(20000):
        tick(cell)
        seen.add(cell.status().state)
        if cell.status().state == S.IDLE:
            break
    assert {S.EXECUTE, S.COMPLETING, S.COMPLETE, S.RESETTING} <= seen
    assert [r.result_code for r in results] == [0]
    assert results[0].client_job_id == "17" and results[0].cycle_time_s > 0
    record = cell.journal.get(ticket.job_id)
    assert record.result_code == 0 and record.ended_at is not None
    steps = cell.journal.steps_of(ticket.job_id)
    assert [s[0] for s in steps if s[3] == "ok"] == list(range(1, 11))
    assert cell.status().parts_processed == 1 and cell.status().last_result.job_id == ticket.job_id


def test_rejects(tmp_path):
    cell, _ = make_cell(tmp_path)
    assert cell.start_job(9, {}, "1", "modbus").reject_code == ResultCode.REJECT_UNKNOWN_TASK
    bad = cell.start_job(1, {"slot": 12}, "2", "modbus")
    assert (bad.reject_code, bad.message) == (
        ResultCode.REJECT_BAD_PARAMS,
        "param 'slot' = 12 is outside [0, 11]",
    )
    assert cell.start_job("pick_place", {}, "3", "modbus").accepted
    assert cell.start_job(1, {}, "4", "modbus").reject_code == ResultCode.REJECT_NOT_READY


def test_same_client_job_id_returns_the_first_job(tmp_path):
    cell, _ = make_cell(tmp_path)
    first = cell.start_job("pick_place", {}, "order-1", "opcua")
    again = cell.start_job("pick_place", {}, "order-1", "opcua")
    assert again.accepted and again.job_id == first.job_id
    assert len(cell.journal.last(10)) == 1


def test_restart_closes_unfinished_job_with_107(tmp_path):
    journal = Journal(tmp_path / "jobs.sqlite").open()
    journal.begin_job("abc", "demo-ur5e", "pick_place", {"slot": 0}, "modbus", "5")
    journal.close()
    cell, _ = make_cell(tmp_path)
    last = cell.status().last_result
    assert (last.job_id, last.result_code) == ("abc", 107)
    assert cell.journal.get("abc").result_text == "interrupted (cellrunner restarted mid-job)"


def test_estop_aborts_and_needs_release_clear_reset(tmp_path):
    arm = ScriptedArm(estop_at_s=0.2)
    cell, _ = make_cell(tmp_path, arm)
    ticket = cell.start_job(1, {}, "1", "modbus")
    ControlLoop(cell).run_job(max_s=30)
    tick(cell, 3)
    assert cell.journal.get(ticket.job_id).result_code == ResultCode.ESTOP
    assert cell.status().state == S.ABORTED and cell.status().estop and not cell.status().ready
    assert cell.command("clear")  # accepted: Clear finds out that the e-stop is still pressed
    tick(cell, 3)
    assert cell.status().state == S.ABORTED and cell.status().estop
    arm.estop_released = True
    tick(cell, 2)
    assert cell.command("clear")
    tick(cell, 3)
    assert arm.powered  # re-armed on the control thread during Clearing
    assert cell.status().state == S.STOPPED
    assert cell.command("reset")
    tick(cell, 3)
    assert cell.status().state == S.IDLE and cell.status().ready


def test_rearming_after_an_estop_is_polled_by_tick_and_never_blocks_it(tmp_path):
    """A real arm takes seconds to power up and release its brakes: Clearing lasts that
    long while every tick returns at once and the status keeps answering."""
    arm = ScriptedArm(estop_at_s=0.2, power_up_ticks=300)
    cell, _ = make_cell(tmp_path, arm)
    cell.start_job(1, {}, "1", "modbus")
    ControlLoop(cell).run_job(max_s=30)
    arm.estop_released = True
    tick(cell, 3)
    arm.powered = False  # the e-stop cut the power
    assert cell.command("clear")
    longest_tick_s, clearing_ticks = 0.0, 0
    for _ in range(400):
        t0 = time.perf_counter()
        tick(cell)
        longest_tick_s = max(longest_tick_s, time.perf_counter() - t0)
        if cell.status().state != S.CLEARING:
            break
        clearing_ticks += 1
        assert not arm.powered
    assert 290 <= clearing_ticks <= 305, clearing_ticks  # one recovery step per tick
    assert arm.powered and cell.status().state == S.STOPPED
    assert longest_tick_s < 0.05, longest_tick_s
    assert cell.command("reset")
    tick(cell, 3)
    assert cell.status().state == S.IDLE and cell.status().ready


def test_clear_unlocks_a_protective_stop_an_aborted_job_left(tmp_path):
    """A job aborted while held by a protective stop leaves the arm stopped: Clear unlocks
    it (once the controller allows, 5 s after the stop), so Reset reaches a ready Idle."""
    arm = ScriptedArm(protective_stop_at_s=0.1)
    cell, _ = make_cell(tmp_path, arm)
    ticket = cell.start_job(1, {}, "1", "modbus")
    tick(cell)
    assert cell.wait_for_plan(timeout_s=60)  # the arm's clock waits for the plan (no race)
    for _ in range(5000):
        tick(cell)
        if cell.status().state == S.HELD:
            break
    assert cell.status().state == S.HELD and cell.status().protective_stop
    assert cell.command("abort")
    tick(cell, 3)
    assert cell.journal.get(ticket.job_id).result_code == ResultCode.ABORTED_BY_PLC
    assert cell.status().state == S.ABORTED and cell.status().protective_stop
    assert cell.command("clear")  # within 5 s of the stop: the controller refuses the unlock
    tick(cell, 3)
    assert cell.status().state == S.ABORTED and arm.unlock_refusals == 1
    tick(cell, 3000)  # 6 s at 500 Hz
    assert cell.command("clear")
    tick(cell, 3)
    assert cell.status().state == S.STOPPED and not cell.status().protective_stop
    assert cell.command("reset")
    tick(cell, 3)
    assert cell.status().state == S.IDLE and cell.status().ready


def test_reset_unlocks_a_protective_stop_latched_in_idle(tmp_path):
    """A protective stop with no job (the arm bumped while idle, or left by a job that
    ended with 100) keeps the cell not READY; the PLC's Reset unlocks it once the
    controller allows (5 s after the stop), and the cell is READY again."""
    arm = ScriptedArm(protective_stop_at_s=0.1)
    cell, _ = make_cell(tmp_path, arm)
    tick(cell, 100)  # 0.2 s at 500 Hz
    status = cell.status()
    assert status.state == S.IDLE and status.protective_stop and not status.ready
    assert cell.command("reset")  # within 5 s of the stop: the controller refuses
    tick(cell, 3)
    assert cell.status().protective_stop and arm.unlock_refusals == 1
    tick(cell, 3000)  # 6 s
    assert cell.command("reset")
    tick(cell, 3)
    status = cell.status()
    assert status.state == S.IDLE and not status.protective_stop and status.ready


def test_abort_by_plc_is_106(tmp_path):
    cell, _ = make_cell(tmp_path)
    ticket = cell.start_job(1, {}, "1", "modbus")
    tick(cell)
    assert cell.wait_for_plan(timeout_s=10)
    tick(cell, 200)
    assert cell.status().state == S.EXECUTE
    assert cell.command("abort")
    tick(cell, 3)
    assert cell.journal.get(ticket.job_id).result_code == ResultCode.ABORTED_BY_PLC
    assert cell.status().state == S.ABORTED


def test_unknown_command_raises_and_illegal_returns_false(tmp_path):
    cell, _ = make_cell(tmp_path)
    with pytest.raises(ValueError, match="unknown command 'jump'"):
        cell.command("jump")
    assert not cell.command("unhold")
