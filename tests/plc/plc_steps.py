"""The PLC's side of a Modbus job, through a :class:`~tests.plc.conftest.PlcProcess`:
raise JobReq and see ACK (or ERROR), drop it, wait for DONE or ERROR."""

from __future__ import annotations

import time

from cellrunner.plc.modbus import (
    CMD_JOB_REQ,
    HANDSHAKE_BITS,
    ST_DONE,
    ST_ERROR,
    ST_JOB_ACK,
    ST_READY,
)
from tests.plc.conftest import PlcProcess


def u16(value: int) -> int:
    return value & 0xFFFF


def raise_job_req(plc: PlcProcess, job_id: int, task: int, params: list[int] = ()) -> list[int]:
    """The PLC's side of the request; returns registers 100-113 once ACK or ERROR shows."""
    assert plc.wait_bits(ST_READY, ST_READY, timeout=3.0)["ok"], plc.read(100, 3)
    assert plc.write(2, [job_id, task] + [u16(p) for p in params])["ok"]
    reply = plc.write(1, [CMD_JOB_REQ])
    assert reply["ok"], reply
    deadline = time.monotonic() + 3.0
    while time.monotonic() < deadline:
        regs = plc.read(100, 14)
        if regs[1] & (ST_JOB_ACK | ST_ERROR):
            return regs
    raise AssertionError(f"no ACK/ERROR: {plc.read(100, 14)}")


def drop_job_req(plc: PlcProcess, command: int = 0) -> None:
    assert plc.write(1, [command])["ok"]
    reply = plc.wait_bits(HANDSHAKE_BITS, 0, timeout=2.0)
    assert reply["ok"], reply


def wait_end(plc: PlcProcess, timeout: float = 5.0) -> list[int]:
    """Registers 100-113 once DONE or ERROR shows."""
    regs = plc.read(100, 14)
    deadline = time.monotonic() + timeout
    while not regs[1] & (ST_DONE | ST_ERROR) and time.monotonic() < deadline:
        time.sleep(0.005)
        regs = plc.read(100, 14)
    assert regs[1] & (ST_DONE | ST_ERROR), regs
    return regs
