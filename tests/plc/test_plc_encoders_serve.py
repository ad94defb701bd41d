"""A belt whose encoder the PLC counts (SPEC section 13, ``encoder: {source: plc,
register: 20}``), tracked by ``serve`` on the twin (its assembly and links, the Modbus
server among them, in the test's process): a PLC on loopback runs the jobs with the
handshake of docs/plc-interface.md (pyModbusTCP) while its encoder task (a pymodbus
client of its own) writes the belt's count into registers 20-21 every 10 ms.

The PLC's count is the twin's own belt travel, and its scan is paced by the twin's time:
the encoder task writes from the control thread, every 5 periods (one of the loop's
observers). On a line the PLC and the belt run in the same time; the real-time twin runs
in bursts on a loaded machine (it catches up after a period that took long), and a PLC
paced by the wall clock would then write counts 10-20 ms of the belt's travel old
(measured: the arm stopped 5.5 mm off the belt's line). A count computed from the belt's
nominal speed and the test's clock would drift from the twin's belt for the same reason.
The count starts 2000 ticks below 2**32 so that it wraps during the first job.

Then the PLC's encoder task stops writing while the arm follows the next block: the arm
does not follow a belt it cannot see (a controlled stop, 100), and the engine logs the
stale count."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import structlog
from pymodbus.client import ModbusTcpClient

from cellrunner.cli.cmd_serve import _Links
from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.cell import CellController
from cellrunner.execution.serving import serve
from cellrunner.model.load import load_cell, load_task
from tests.plc_belt_rig import plc_belt_project
from tests.rig import (
    DONE,
    ERROR,
    JOB_ACK,
    JOB_REQ,
    READY,
    free_port,
    modbus_client,
    wait_bits,
)

HOST = "127.0.0.173"
TICKS_PER_M = 4000
#: the count at the twin's belt travel 0: it wraps (2**32 -> 0) 2000 ticks (0.5 m) on
COUNT_AT_ZERO = 2**32 - 2000
TRAY_PART_XYZ = (0.35, 0.55, 0.826)  # the block's centre once placed (the grip frame)
#: the PLC's scan: it writes the count every this many periods of the twin (10 ms)
SCAN_PERIODS = 5
#: the belt's speed while the line runs: the reference cell's speed_max
SPEED_MPS = 0.30


class _TwinBelt:
    """The twin's belt, its PLC's encoder task and the arm, each period of the control
    thread (an observer of the loop). Every ``SCAN_PERIODS`` periods of the twin's time
    the PLC's encoder task (a pymodbus client) writes the belt's count into registers
    20-21 (once ``port`` is set and while ``writing``); the test reads the arm's joints
    and where the blocks are. The test holds the line (``speed_mps``) until the arm waits
    over the belt, as a line's PLC would start it."""

    def __init__(self) -> None:
        self.q_rad: np.ndarray | None = None
        self.parts: dict[str, np.ndarray] = {}
        self.speed_mps = 0.0
        self._speed_set: float | None = None
        self.port: int | None = None
        self.writing = threading.Event()
        self.writing.set()
        self.writes = 0
        self._client: ModbusTcpClient | None = None
        self._ticks = 0

    def __call__(self, cell: CellController) -> None:
        backend: Any = cell.backend
        world = backend.world
        if self.speed_mps != self._speed_set:
            world.belts.set_speed("belt", self.speed_mps)
            self._speed_set = self.speed_mps
        self._ticks += 1
        if self._ticks % SCAN_PERIODS == 0 and self.port is not None and self.writing.is_set():
            travel = backend.conveyor_travel_m("belt")
            count = (COUNT_AT_ZERO + round(travel * TICKS_PER_M)) % 2**32
            if self._client is None:
                self._client = ModbusTcpClient(HOST, port=self.port, timeout=2)
            if self._client.connected or self._client.connect():
                self._client.write_registers(20, [count >> 16, count & 0xFFFF])
                self.writes += 1
        if self._ticks % 10 == 0:
            self.q_rad = np.array(world.q_measured())
            self.parts = {
                name: np.array(world.data.xpos[body])
                for name, body in world.ids.part_bodies.items()
            }

    def close(self) -> None:
        if self._client is not None:
            self._client.close()


def _cell(tmp_path: Path, port: int) -> Path:
    plc = f"plc:\n  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 2.0}}\n"
    return plc_belt_project(tmp_path, extra=plc)[0]


def _placed(belt: _TwinBelt) -> list[str]:
    return [
        name
        for name, xyz in belt.parts.items()
        if np.linalg.norm(xyz - np.array(TRAY_PART_XYZ)) < 0.01
    ]


def _job(
    client: Any,
    job_id: int,
    belt: _TwinBelt,
    why: Any,
    *,
    stale: bool,
) -> list[int]:
    """One job of the reference task as the PLC runs it, the line held until the job
    waits at its track step (register 106, 1-based: step 2); with ``stale``, the encoder
    task stops writing 0.3 s after the arm set off after the block. The registers at its end."""
    beat = [1000 * job_id]
    belt.speed_mps = 0.0
    wait_bits(client, READY, 30, beat)
    client.write_multiple_registers(2, [job_id, 1])
    client.write_single_register(1, JOB_REQ)
    wait_bits(client, JOB_ACK, 5, beat)
    deadline = time.monotonic() + 120
    regs = wait_bits(client, 0, 5, beat)
    while time.monotonic() < deadline and regs[6] < 2 and not regs[1] & (DONE | ERROR):
        regs = wait_bits(client, 0, 5, beat)
    time.sleep(0.5)  # the arm stands over the belt
    assert belt.q_rad is not None
    q0 = belt.q_rad.copy()
    belt.speed_mps = SPEED_MPS
    if stale:
        while time.monotonic() < deadline and not regs[1] & (DONE | ERROR):
            q = belt.q_rad
            if np.max(np.abs(q - q0)) > 0.02:
                break
            regs = wait_bits(client, 0, 5, beat)
        assert not regs[1] & (DONE | ERROR), (
            f"job {job_id} ended before the arm moved",
            regs,
            why(),
        )
        time.sleep(0.3)  # the arm follows the block
        belt.writing.clear()
    while time.monotonic() < deadline and not regs[1] & (DONE | ERROR):
        regs = wait_bits(client, 0, 5, beat)
        time.sleep(0.05)
    client.write_single_register(1, 0)
    return regs


def test_serve_tracks_a_belt_the_plc_counts_and_stops_when_the_count_goes_stale(
    tmp_path: Path,
) -> None:
    port = free_port(HOST)
    cell = load_cell(_cell(tmp_path, port))
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    log = structlog.get_logger()
    belt = _TwinBelt()
    stop = threading.Event()
    switch = sys.getswitchinterval()
    sys.setswitchinterval(0.001)  # as serve runs: the PLC's threads get the interpreter promptly
    with structlog.testing.capture_logs() as events:
        assembled = assemble_cell(
            cell,
            tasks,
            "sim",
            warm=True,
            log=log,
            wait_for_unhold=True,
            feed_parts=True,
            realtime=True,
        )
        assembled.loop.add_observer(belt)
        links = _Links(assembled, cell, tasks, None, log)
        server = threading.Thread(
            target=serve,
            args=(assembled, stop, log),
            kwargs={
                "stop_reason": lambda: "the test is over",
                "open_links": links.open,
                "on_serving": lambda: None,
            },
            name="serve",
        )
        server.start()
        try:
            client = modbus_client(port, HOST)
            belt.port = port

            def why() -> list[Any]:  # the jobs' ends, as the engine logged them
                return [e.get("message") for e in events if e.get("event") == "job_end"]

            regs = _job(client, 1, belt, why, stale=False)
            assert regs[1] & DONE and regs[5] == 0, (regs, why())
            time.sleep(0.2)  # the observer's next look at the blocks
            assert len(_placed(belt)) == 1, belt.parts
            assert belt.writes > 100  # the count the job tracked came from the PLC
            stale = _job(client, 2, belt, why, stale=True)
            time.sleep(0.3)
        finally:
            stop.set()
            server.join(30)
            belt.close()
            sys.setswitchinterval(switch)
    assert not server.is_alive()
    assert stale[1] & ERROR and stale[5] == 100, stale
    found = [e for e in events if e.get("event") == "plc_encoder_stale"]
    assert found and found[0]["conveyor"] == "belt", [e.get("event") for e in events][-30:]
    assert "no write of registers 20-21" in found[-1]["why"], found
