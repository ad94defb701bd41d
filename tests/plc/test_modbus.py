"""SPEC section 7 over real sockets: the cell's Modbus server, PLC clients in processes.

Every test runs twice: with pymodbus's client and with pyModbusTCP (independent).
"""

from __future__ import annotations

import itertools
import time

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.modbus import (
    CMD_ABORT,
    CMD_HOLD,
    CMD_JOB_REQ,
    CMD_RESET,
    CMD_UNHOLD,
    HANDSHAKE_BITS,
    ST_BUSY,
    ST_DONE,
    ST_ERROR,
    ST_HELD,
    ST_JOB_ACK,
    ST_PLC_WATCHDOG,
    ST_PROTECTIVE_STOP,
    ST_READY,
    ST_REJECTED,
)
from tests.plc.conftest import HEARTBEAT_TIMEOUT_S, PlcProcess
from tests.plc.plc_steps import drop_job_req, raise_job_req, wait_end

ILLEGAL_DATA_ADDRESS = 2


def test_full_handshake_ok(plc: PlcProcess, cell: FakeCell) -> None:
    plc.call("heartbeat", on=True)
    regs = raise_job_req(plc, 17, 1, [5, -3])
    assert regs[1] & (ST_JOB_ACK | ST_BUSY) == ST_JOB_ACK | ST_BUSY
    assert not regs[1] & ST_READY
    assert regs[3] == 17  # job id echo
    regs = wait_end(plc)
    assert regs[1] & ST_DONE and not regs[1] & (ST_BUSY | ST_ERROR)
    assert regs[4] == 17 and regs[5] == 0
    assert regs[8] == 0 and 0 < regs[9] < 5000  # cycle time ms, uint32 high word first
    assert (regs[10], regs[11]) == (70_001 >> 16, 70_001 & 0xFFFF)
    drop_job_req(plc)
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"]
    job = cell.finished[-1]
    assert (job.source, job.client_job_id, job.result_code) == ("modbus", "17", 0)


def test_nok_completes_with_done_and_counts_defective(plc: PlcProcess, cell: FakeCell) -> None:
    cell._script.extend([1])  # next job: no part
    raise_job_req(plc, 18, 1, [0])
    regs = wait_end(plc)
    assert regs[1] & ST_DONE and not regs[1] & ST_ERROR
    assert (regs[4], regs[5], regs[7]) == (18, 1, 1)  # id, NOK code, retries used
    assert (regs[12], regs[13]) == (1, 0)  # 65536 defective: high word first
    drop_job_req(plc)


def test_fault_ends_with_error(plc: PlcProcess, cell: FakeCell) -> None:
    cell._script.extend([105])
    raise_job_req(plc, 19, 2)
    regs = wait_end(plc)
    assert regs[1] & ST_ERROR and not regs[1] & (ST_DONE | ST_REJECTED | ST_BUSY)
    assert (regs[4], regs[5]) == (19, 105)
    drop_job_req(plc)


def test_rejects_unknown_task_bad_params_not_ready(plc: PlcProcess, cell: FakeCell) -> None:
    for job_id, task, params, code in [
        (21, 99, [], 10),
        (22, 1, [50], 11),
        (23, 1, [0, -51], 11),
        (0, 1, [], 11),
    ]:
        regs = raise_job_req(plc, job_id, task, params)
        assert regs[1] & (ST_ERROR | ST_REJECTED) == ST_ERROR | ST_REJECTED, (job_id, regs)
        assert not regs[1] & (ST_JOB_ACK | ST_BUSY)
        assert (regs[3], regs[4], regs[5]) == (job_id, job_id, code)
        drop_job_req(plc)
    # not ready: ABORT puts the cell in Aborted (9)
    assert plc.write(1, [CMD_ABORT])["ok"]
    assert plc.wait_bits(0xFFFF, 9, addr=102, timeout=2.0)["ok"]
    assert not plc.read(101)[0] & ST_READY
    assert plc.write(2, [24, 1])["ok"] and plc.write(1, [CMD_ABORT | CMD_JOB_REQ])["ok"]
    regs = plc.read(100, 14)
    assert regs[1] & ST_REJECTED and (regs[3], regs[5]) == (24, 12)
    # RESET rising edge: Clear (Aborted -> Stopped) then Reset (-> Idle)
    assert plc.write(1, [CMD_RESET])["ok"]
    assert plc.wait_bits(0xFFFF, 4, addr=102, timeout=3.0)["ok"]
    assert plc.wait_bits(ST_READY | HANDSHAKE_BITS, ST_READY, timeout=2.0)["ok"]
    assert cell.commands[-3:] == ["abort", "clear", "reset"]
    assert not any(r.client_job_id in {"21", "22", "23", "24"} for r in cell.finished)


def test_reset_clears_a_protective_stop_latched_in_idle(plc: PlcProcess, cell: FakeCell) -> None:
    """A protective stop with no job (a job that ended with 100, or a bump while idle)
    leaves the cell in Idle but not READY; the PLC's RESET edge is what unlocks it."""
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"]
    cell.inject_protective_stop()
    assert plc.wait_bits(ST_READY | ST_PROTECTIVE_STOP, ST_PROTECTIVE_STOP, timeout=2.0)["ok"]
    assert plc.read(102)[0] == 4  # still Idle
    assert plc.write(1, [CMD_RESET])["ok"]
    assert plc.wait_bits(ST_READY | ST_PROTECTIVE_STOP, ST_READY, timeout=2.0)["ok"]
    assert cell.commands[-1:] == ["reset"]
    plc.write(1, [0])


def test_plc_watchdog_refuses_jobs_until_heartbeat_moves(plc: PlcProcess, cell: FakeCell) -> None:
    plc.call("heartbeat", on=True)
    time.sleep(0.35)  # a few beats: the watchdog arms on the first change
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"]
    plc.call("heartbeat", on=False)
    t0 = time.monotonic()
    reply = plc.wait_bits(ST_PLC_WATCHDOG, ST_PLC_WATCHDOG, timeout=HEARTBEAT_TIMEOUT_S + 1.0)
    assert reply["ok"]
    assert HEARTBEAT_TIMEOUT_S - 0.15 < time.monotonic() - t0 < HEARTBEAT_TIMEOUT_S + 0.6
    assert not plc.read(101)[0] & ST_READY
    assert plc.write(2, [31, 2])["ok"] and plc.write(1, [CMD_JOB_REQ])["ok"]
    regs = plc.read(100, 14)
    assert regs[1] & ST_REJECTED and regs[5] == 12
    drop_job_req(plc)
    plc.call("heartbeat", on=True)
    assert plc.wait_bits(ST_PLC_WATCHDOG | ST_READY, ST_READY, timeout=2.0)["ok"]
    regs = raise_job_req(plc, 32, 2)
    assert regs[1] & ST_JOB_ACK
    assert wait_end(plc)[5] == 0
    drop_job_req(plc)


def test_watchdog_holds_running_job_then_unhold_completes(plc: PlcProcess, cell: FakeCell) -> None:
    plc.call("heartbeat", on=True)
    time.sleep(0.35)
    regs = raise_job_req(plc, 41, 3)
    assert regs[1] & ST_BUSY
    plc.call("heartbeat", on=False)
    assert plc.wait_bits(ST_PLC_WATCHDOG | ST_HELD, ST_PLC_WATCHDOG | ST_HELD, timeout=2.0)["ok"]
    assert cell.status().hold_source == "plc_watchdog"  # not the words of a PLC's Hold
    # Unhold is a command of Held (11), not of Holding (10): a PLC waits for it
    assert plc.wait_bits(0xFFFF, 11, addr=102, timeout=2.0)["ok"]
    plc.call("heartbeat", on=True)
    assert plc.wait_bits(ST_PLC_WATCHDOG, 0, timeout=1.0)["ok"]
    assert plc.read(101)[0] & ST_HELD  # no automatic unhold: the PLC decides
    assert plc.write(1, [CMD_JOB_REQ | CMD_UNHOLD])["ok"]
    regs = wait_end(plc, timeout=5.0)
    assert regs[1] & ST_DONE and (regs[4], regs[5]) == (41, 0)
    drop_job_req(plc)


def test_hold_unhold_abort_bits(plc: PlcProcess, cell: FakeCell) -> None:
    raise_job_req(plc, 51, 3)
    assert plc.write(1, [CMD_JOB_REQ | CMD_HOLD])["ok"]
    assert plc.wait_bits(0xFFFF, 11, addr=102, timeout=2.0)["ok"]
    assert plc.read(101)[0] & ST_HELD
    assert (cell.status().hold_source, cell.status().hold_reason) == ("plc", "hold requested")
    assert plc.write(1, [CMD_JOB_REQ | CMD_UNHOLD])["ok"]
    assert plc.wait_bits(0xFFFF, 6, addr=102, timeout=2.0)["ok"]
    assert plc.write(1, [CMD_JOB_REQ | CMD_ABORT])["ok"]
    regs = wait_end(plc)
    assert regs[1] & ST_ERROR and (regs[4], regs[5]) == (51, 106)
    drop_job_req(plc, CMD_ABORT)
    assert plc.write(1, [CMD_RESET])["ok"]
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"]


def test_writes_outside_plc_registers_get_exception_02(plc: PlcProcess) -> None:
    before = plc.read(101, 13)
    for addr, values in [
        (100, [1]),
        (101, [0, 0]),
        (105, [7]),
        (119, [1]),
        (29, [0, 0]),
        (30, [1]),
        (200, [1]),
    ]:
        reply = plc.write(addr, values)
        assert not reply["ok"] and reply["exception"] == ILLEGAL_DATA_ADDRESS, (addr, reply)
    assert plc.read(29)[0] == 0  # the refused 29-30 write changed nothing
    after = plc.read(101, 13)
    assert after[3:] == before[3:]
    assert plc.write(19, [1234])["ok"] and plc.read(19) == [1234]
    # SPEC section 13: 20-29 carry conveyor encoder counts (uint32, high word first)
    assert plc.write(20, [0x0001, 0x86A0])["ok"] and plc.read(20, 2) == [0x0001, 0x86A0]
    reply = plc.call("read", addr=118, count=4)
    assert not reply["ok"] and reply["exception"] == ILLEGAL_DATA_ADDRESS


def test_cell_heartbeat_increments_at_least_every_200ms(plc: PlcProcess) -> None:
    changes: list[float] = []
    last = plc.read(100)[0]
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        value = plc.read(100)[0]
        if value != last:
            assert value == (last + 1) & 0xFFFF
            changes.append(time.monotonic())
            last = value
        time.sleep(0.005)
    gaps = [b - a for a, b in itertools.pairwise(changes)]
    assert len(changes) >= 5 and max(gaps) <= 0.2, gaps
