"""ModbusLink tick by tick against a FakeCell advanced by hand (no sockets, fake clock)."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.modbus import (
    CMD_JOB_REQ,
    EXC_ILLEGAL_ADDRESS,
    ST_BUSY,
    ST_DONE,
    ST_ERROR,
    ST_JOB_ACK,
    ST_PLC_WATCHDOG,
    ST_READY,
    ModbusConfig,
    ModbusLink,
    split_uint32,
    to_int16,
)
from cellrunner.plc.port import CellPort, JobResult, ResultCode
from tests.plc.conftest import plc_test_tasks


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def make(**kw: object) -> tuple[FakeCell, ModbusLink, Clock]:
    clock = Clock()
    cell = FakeCell(tasks=plc_test_tasks(), clock=lambda: clock.t + 100.0, **kw)  # type: ignore[arg-type]
    link = ModbusLink(cell, heartbeat_timeout_s=1.0, clock=clock)
    cell.add_result_listener(link.on_result)
    link.restore()
    return cell, link, clock


def run_until(cell: FakeCell, link: ModbusLink, clock: Clock, bits: int, limit: int = 500) -> None:
    for _ in range(limit):
        clock.t += 0.02
        cell.step(clock.t + 100.0)  # the fake's own clock runs far ahead: steps finish
        link.tick()
        if link.regs[101] & bits:
            return
    raise AssertionError(f"status bits {link.regs[101]:#x} never showed {bits:#x}")


def test_fake_cell_and_the_engine_implement_the_port_with_its_signatures() -> None:
    from cellrunner.execution.cell import CellController
    from tests.protocol_check import assert_implements

    assert_implements(FakeCell(), CellPort)
    assert_implements(CellController.__new__(CellController), CellPort)


def test_the_signature_check_catches_a_drifted_method() -> None:
    from tests.protocol_check import assert_implements

    class Drifted(FakeCell):
        def start_job(self, task, params):  # type: ignore[override]  # lost client_job_id, source
            raise NotImplementedError

    with pytest.raises(AssertionError, match=r"Drifted\.start_job"):
        assert_implements(Drifted(), CellPort)


def test_words() -> None:
    assert to_int16(0xFFFD) == -3 and to_int16(5) == 5
    assert split_uint32(70_001) == (1, 4465)
    assert split_uint32(-5) == (0, 0) and split_uint32(2**40) == (0xFFFF, 0xFFFF)


def test_refused_write_changes_nothing() -> None:
    _, link, _ = make()
    assert link.write(28, [1, 2, 3]) == EXC_ILLEGAL_ADDRESS  # 20-29: encoders (SPEC 13)
    assert link.regs[28:31] == [0, 0, 0]
    assert link.write(18, [1, 2, 3]) is None and link.regs[18:21] == [1, 2, 3]
    assert link.write(100, [1]) == EXC_ILLEGAL_ADDRESS
    assert link.read(119, 1) == [0] and link.read(119, 2) == EXC_ILLEGAL_ADDRESS


def test_single_write_of_request_and_job_req_latches_params() -> None:
    cell, link, clock = make()
    assert link.regs[101] & ST_READY
    assert link.write(1, [CMD_JOB_REQ, 7, 1, 11, 0xFFCE]) is None  # one FC16 write 1..5
    assert link.regs[101] & (ST_JOB_ACK | ST_BUSY) == ST_JOB_ACK | ST_BUSY
    assert link.regs[103] == 7
    run_until(cell, link, clock, ST_DONE)
    assert cell.finished[-1].client_job_id == "7"
    assert link.regs[104:106] == [7, 0]


def test_early_drop_of_job_req_keeps_busy_then_publishes_without_done() -> None:
    cell, link, clock = make()
    link.write(2, [9, 2])
    link.write(1, [CMD_JOB_REQ])
    link.write(1, [0])
    assert link.regs[101] & ST_BUSY
    run_until(cell, link, clock, ST_READY)
    assert link.regs[104:106] == [9, 0]
    assert not link.regs[101] & (ST_DONE | ST_ERROR | ST_BUSY | ST_JOB_ACK)


def test_watchdog_arms_on_first_heartbeat_change_and_clears_on_next() -> None:
    _cell, link, clock = make()
    clock.t += 5.0
    link.tick()
    assert not link.regs[101] & ST_PLC_WATCHDOG  # never seen a heartbeat: not armed
    link.write(0, [1])
    clock.t += 1.01
    link.tick()
    assert link.regs[101] & ST_PLC_WATCHDOG and not link.regs[101] & ST_READY
    link.write(0, [1])  # same value: not a beat
    assert link.watchdog
    link.write(0, [2])
    assert not link.watchdog and link.regs[101] & ST_READY


def test_job_interrupted_by_restart_is_published_and_replayed_once() -> None:
    interrupted = JobResult(
        job_id="J000041",
        result_code=ResultCode.INTERRUPTED,
        result_text="interrupted",
        retries=0,
        end_time=datetime.now(UTC),
        client_job_id="41",
        source="modbus",
    )
    cell, link, _clock = make(last_result=interrupted)
    assert link.regs[104:106] == [41, 107]
    link.write(2, [41, 1])  # the PLC, restarted with us, still asks for job 41
    link.write(1, [CMD_JOB_REQ])
    assert link.regs[101] & (ST_JOB_ACK | ST_ERROR) == ST_JOB_ACK | ST_ERROR
    assert link.regs[103:106] == [41, 41, 107]
    assert cell.finished == []  # not run a second time
    link.write(1, [0])
    link.write(2, [42, 2])
    link.write(1, [CMD_JOB_REQ])
    assert link.regs[101] & ST_BUSY


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        (
            {"bind": "0.0.0.0", "port": 1502, "heartbeat_timeout": 2},
            ModbusConfig("0.0.0.0", 1502, 2.0),
        ),
        ({}, ModbusConfig("127.0.0.1", 502, 1.5)),
    ],
)
def test_config_from_cell_file(data: dict, expected: ModbusConfig) -> None:
    assert ModbusConfig.from_mapping(data) == expected


def test_port_in_use_is_a_cellrunner_error() -> None:
    import socket

    from cellrunner.errors import CellrunnerError
    from cellrunner.plc.service import PlcService

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with FakeCell() as cell:
            service = PlcService(cell, {"modbus": {"bind": "127.0.0.1", "port": port}})
            with pytest.raises(
                CellrunnerError, match=f"cannot listen for Modbus TCP on 127.0.0.1:{port}"
            ):
                service.start(timeout_s=10)
