"""Handshake edge cases found with an independent PLC (issue 13), each over real sockets
with the PLC in its own process (both client libraries)."""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.modbus import (
    CMD_ABORT,
    CMD_JOB_REQ,
    HANDSHAKE_BITS,
    ST_BUSY,
    ST_DONE,
    ST_ERROR,
    ST_JOB_ACK,
    ST_READY,
    ST_REJECTED,
)
from cellrunner.plc.service import PlcService
from tests.plc.conftest import HERE, PlcProcess
from tests.plc.plc_steps import drop_job_req, raise_job_req, wait_end


def test_job_req_toggled_fast_with_the_same_id_never_shows_a_reject(
    plc: PlcProcess, cell: FakeCell
) -> None:
    regs = raise_job_req(plc, 31, 3)  # task 3 runs ~1.2 s
    assert regs[1] & (ST_JOB_ACK | ST_BUSY) == ST_JOB_ACK | ST_BUSY
    for _ in range(5):  # 1-0-1 as fast as the PLC can
        assert plc.write(1, [0])["ok"] and plc.write(1, [CMD_JOB_REQ])["ok"]
        regs = plc.read(100, 14)
        assert not regs[1] & (ST_REJECTED | ST_ERROR), regs
        assert regs[1] & (ST_JOB_ACK | ST_BUSY) == ST_JOB_ACK | ST_BUSY, regs
    regs = wait_end(plc)
    assert regs[1] & ST_DONE and (regs[4], regs[5]) == (31, 0), regs
    drop_job_req(plc)
    assert [j.client_job_id for j in cell.finished] == ["31"]


def test_a_trigger_while_busy_keeps_the_running_jobs_ack_and_busy(
    plc: PlcProcess, cell: FakeCell
) -> None:
    raise_job_req(plc, 41, 3)
    assert plc.write(1, [0])["ok"]  # the PLC drops the request early (job still running)...
    assert (
        plc.write(2, [42, 2])["ok"] and plc.write(1, [CMD_JOB_REQ])["ok"]
    )  # ...and asks for another
    regs = plc.read(100, 14)
    assert regs[1] & (ST_JOB_ACK | ST_BUSY) == ST_JOB_ACK | ST_BUSY, (
        regs
    )  # the running job's bits stay
    assert regs[1] & ST_REJECTED and (regs[4], regs[5]) == (42, 12), regs  # the new one is refused
    assert regs[3] == 41  # the echo still names the running job
    assert plc.write(1, [0])["ok"]
    regs = plc.read(100, 14)
    assert regs[1] & ST_BUSY and not regs[1] & ST_REJECTED, regs
    deadline = time.monotonic() + 5
    while plc.read(101)[0] & ST_BUSY and time.monotonic() < deadline:
        time.sleep(0.01)
    regs = plc.read(100, 14)
    assert (regs[4], regs[5]) == (41, 0) and not regs[1] & ST_BUSY, regs
    assert [j.client_job_id for j in cell.finished] == ["41"]


def test_the_same_id_after_its_job_ended_gets_the_result_not_a_second_run(
    plc: PlcProcess, cell: FakeCell
) -> None:
    raise_job_req(plc, 51, 2)
    assert wait_end(plc)[5] == 0
    drop_job_req(plc)
    regs = raise_job_req(plc, 51, 2)  # asked again (a PLC retry, a restart)
    assert regs[1] & (ST_JOB_ACK | ST_DONE) == ST_JOB_ACK | ST_DONE and not regs[1] & ST_BUSY, regs
    assert (regs[4], regs[5]) == (51, 0)
    drop_job_req(plc)
    time.sleep(0.2)
    assert [j.client_job_id for j in cell.finished] == ["51"]  # ran once
    regs = raise_job_req(plc, 52, 2)  # a new id runs
    assert regs[1] & ST_BUSY or regs[1] & ST_DONE
    wait_end(plc)
    drop_job_req(plc)
    assert [j.client_job_id for j in cell.finished] == ["51", "52"]


def test_a_job_that_ended_before_a_restart_is_not_run_again(cell: FakeCell) -> None:
    """kill -9 right after DONE: the new process finds the job's result as the last one
    (the journal) and answers the re-raised id with it."""
    from cellrunner.plc.port import JobResult, ResultCode

    cell.last_result = JobResult(
        "j-61", ResultCode.OK, "OK", 1.5, source="modbus", client_job_id="61"
    )
    service = PlcService(cell, {"modbus": {"bind": "127.0.0.1", "port": 0}})
    service.start()
    plc = PlcProcess("pyModbusTCP", *service.modbus_address)
    try:
        regs = raise_job_req(plc, 61, 2)
        assert regs[1] & ST_DONE and not regs[1] & ST_BUSY and (regs[4], regs[5]) == (61, 0), regs
        drop_job_req(plc)
        assert cell.finished == []  # nothing ran
    finally:
        plc.close()
        service.stop()


def test_pipelined_requests_in_one_segment_are_all_answered(modbus_service: PlcService) -> None:
    """Three read requests written in one send(): three answers, in order."""
    host, port = modbus_service.modbus_address
    frames = b"".join(struct.pack(">HHHBBHH", tid, 0, 6, 1, 3, 100, 2) for tid in (1, 2, 3))
    with socket.create_connection((host, port), timeout=3) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.sendall(frames)
        data, deadline = b"", time.monotonic() + 3
        while len(data) < 3 * 13 and time.monotonic() < deadline:
            data += sock.recv(4096)
    tids = [struct.unpack(">H", data[i : i + 2])[0] for i in range(0, len(data), 13)]
    assert tids == [1, 2, 3], data.hex()


def test_ready_comes_back_after_a_busy_reject(plc: PlcProcess, cell: FakeCell) -> None:
    raise_job_req(plc, 71, 2)
    wait_end(plc)
    drop_job_req(plc)
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"]


def _raw_exchange(service: PlcService, chunks: list[bytes], expect: int) -> dict:
    """Send ``chunks`` from a raw-socket client in its own process; its answers."""
    host, port = service.modbus_address
    spec = {"chunks": [c.hex() for c in chunks], "pause_s": 0.2, "expect": expect}
    out = subprocess.run(
        [sys.executable, str(HERE / "raw_modbus.py"), host, str(port)],
        input=json.dumps(spec),
        capture_output=True,
        text=True,
        timeout=20,
        check=True,
    )
    return json.loads(out.stdout)


def _write_frame(tid: int, address: int, value: int) -> bytes:
    return struct.pack(">HHHBBHH", tid, 0, 6, 1, 6, address, value)


def _read_frame(tid: int, address: int, count: int) -> bytes:
    return struct.pack(">HHHBBHH", tid, 0, 6, 1, 3, address, count)


@pytest.mark.parametrize("n", [22, 23, 50, 400])
def test_a_segment_of_any_size_gets_every_frame_answered_in_order(
    modbus_service: PlcService, n: int
) -> None:
    """n pairs (write register 4 = i, read it back) in one segment: 2n answers, in
    order, each read seeing the write before it (pymodbus alone drops past 264 bytes)."""
    frames = b"".join(
        _write_frame(2 * i + 1, 4, i) + _read_frame(2 * i + 2, 4, 1) for i in range(n)
    )
    got = _raw_exchange(modbus_service, [frames], expect=2 * n)["frames"]
    assert [f["tid"] for f in got] == list(range(1, 2 * n + 1))
    assert [f["fc"] for f in got] == [6, 3] * n
    reads = [int(f["pdu"][2:], 16) for f in got[1::2]]
    assert reads == list(range(n))


def test_a_frame_split_across_segments_waits_for_its_rest(modbus_service: PlcService) -> None:
    frames = b"".join(_read_frame(tid, 100, 2) for tid in (1, 2, 3)) + _write_frame(4, 4, 7)
    cut = len(frames) - 5  # the last write's last 5 bytes come 0.2 s later
    got = _raw_exchange(modbus_service, [frames[:7], frames[7:cut], frames[cut:]], expect=4)
    assert [(f["tid"], f["fc"]) for f in got["frames"]] == [(1, 3), (2, 3), (3, 3), (4, 6)]
    assert modbus_service.modbus.link.regs[4] == 7


def test_a_header_no_frame_can_have_closes_the_connection(modbus_service: PlcService) -> None:
    bad = struct.pack(">HHHBBHH", 1, 7, 6, 1, 3, 100, 1)  # protocol id 7
    got = _raw_exchange(modbus_service, [_read_frame(1, 100, 1) + bad], expect=2)
    assert [f["tid"] for f in got["frames"]] == [1] and got["closed"]


@pytest.fixture
def second_plc(modbus_service: PlcService) -> Iterator[PlcProcess]:
    """Another client (pyModbusTCP, its own process) on the same cell."""
    client = PlcProcess("pyModbusTCP", *modbus_service.modbus_address)
    try:
        yield client
    finally:
        client.close()


def _request_while_busy(other: PlcProcess, job_id: int) -> list[int]:
    """The other client's request for a new id: its own rising JOB_REQ edge."""
    assert other.write(2, [job_id, 2])["ok"]
    assert other.write(1, [0])["ok"] and other.write(1, [CMD_JOB_REQ])["ok"]
    return other.read(100, 14)


def test_a_reject_mid_job_never_shows_on_the_running_jobs_end(
    plc: PlcProcess, second_plc: PlcProcess, cell: FakeCell
) -> None:
    """Order 1: the second request is still held when the running job ends."""
    raise_job_req(plc, 81, 3)  # ~1.2 s
    regs = _request_while_busy(second_plc, 82)
    # REJECTED beside the job's ACK+BUSY, never ERROR (a PLC waiting for the job's DONE or
    # ERROR would take it for the end); echo 103: the job; 104/105: the refused id, 12
    assert regs[1] & HANDSHAKE_BITS == ST_JOB_ACK | ST_BUSY | ST_REJECTED, regs
    assert (regs[3], regs[4], regs[5]) == (81, 82, 12), regs
    regs = wait_end(plc)
    assert regs[1] & HANDSHAKE_BITS == ST_JOB_ACK | ST_DONE, regs  # the job's own end only
    assert (regs[3], regs[4], regs[5]) == (81, 81, 0), regs
    drop_job_req(plc)
    assert [j.client_job_id for j in cell.finished] == ["81"]


def test_a_reject_released_mid_job_leaves_the_job_its_end(
    plc: PlcProcess, second_plc: PlcProcess, cell: FakeCell
) -> None:
    """Order 2: the second request is dropped before the running job ends. JOB_REQ is one
    bit for both clients, so the drop also ends the handshake early: at the end the
    job's result is in 104-113, no DONE, no ERROR, and READY returns."""
    raise_job_req(plc, 83, 3)
    assert _request_while_busy(second_plc, 84)[1] & ST_REJECTED
    assert second_plc.write(1, [0])["ok"]
    regs = second_plc.read(100, 14)
    assert regs[1] & HANDSHAKE_BITS == ST_JOB_ACK | ST_BUSY, regs
    assert plc.wait_bits(ST_READY, ST_READY, timeout=5.0)["ok"]
    regs = plc.read(100, 14)
    assert not regs[1] & HANDSHAKE_BITS and (regs[4], regs[5]) == (83, 0), regs
    assert [j.client_job_id for j in cell.finished] == ["83"]


def test_a_running_job_that_fails_after_a_reject_shows_error_without_rejected(
    plc: PlcProcess, second_plc: PlcProcess, cell: FakeCell
) -> None:
    """A running job that ends ERROR after a reject: ERROR, never REJECTED, 105 its code."""
    raise_job_req(plc, 85, 3)
    regs = _request_while_busy(second_plc, 86)
    assert regs[1] & HANDSHAKE_BITS == ST_JOB_ACK | ST_BUSY | ST_REJECTED, regs
    assert plc.write(1, [CMD_JOB_REQ | CMD_ABORT])["ok"]
    regs = wait_end(plc)
    assert regs[1] & HANDSHAKE_BITS == ST_JOB_ACK | ST_ERROR, regs
    assert (regs[4], regs[5]) == (85, 106), regs
