"""The PLC's encoder registers as the engine reads them (cellrunner.execution.plc_encoders):
a count written every scan, read every period, is a line (not a staircase) through a
wrap; a belt that stops reads stopped within a few scans (5); a silent PLC leaves the belt
unmeasured until it writes again. The registers come from the Modbus server's own
register image (ModbusLink, driven as pymodbus drives it); times are the engine's."""

from __future__ import annotations

import random
import re
from typing import Any

import numpy as np
import pytest

from cellrunner.execution.belt_watch import BeltWatch
from cellrunner.execution.plc_encoders import STALE_S, PlcEncoders
from cellrunner.model.encoder_count import WrappingCount
from cellrunner.model.load import load_cell
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.plc.fake import FakeCell
from cellrunner.plc.modbus import ModbusLink
from tests.plc.conftest import plc_test_tasks
from tests.plc_belt_rig import plc_belt_project

PERIOD_S = 0.002  # the engine's (a UR's)
SCAN_S = 0.012  # the PLC's
TICKS_PER_M = 4000
SPEED_MPS = 0.30


class _Log:
    """The events the measurement logs."""

    def __init__(self) -> None:
        self.events: list[tuple[str, dict[str, Any]]] = []

    def info(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))

    warning = info

    def bind(self, **fields: Any) -> _Log:
        return self


@pytest.fixture(scope="module")
def conveyors(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    cell_path, _ = plc_belt_project(tmp_path_factory.mktemp("cell"), register=22)
    cell = load_cell(cell_path)
    return dict(cell.cell.conveyors)


class _Line:
    """A PLC writing a belt's count into registers 22-23 of the Modbus server's register
    image every scan (its arrival late by up to ``jitter_s``), and the engine reading it
    every period."""

    def __init__(self, conveyors: dict[str, Any], jitter_s: float = 0.003) -> None:
        self.link = ModbusLink(FakeCell(tasks=plc_test_tasks()), clock=lambda: 0.0)
        self.log = _Log()
        self.measure = PlcEncoders(conveyors, lambda: self.link.encoder_registers, None, self.log)
        self.rng = random.Random(7)
        self.jitter_s = jitter_s
        self.next_write_s = 0.0
        self.arrival_s: float | None = None
        self.pending = 0

    def run(self, until_s: float, t_s: float, travel_m: Any, writing: bool = True) -> list[Any]:
        """Periods from ``t_s`` to ``until_s``: ``(time, true travel, read travel)`` each."""
        out = []
        n = round((until_s - t_s) / PERIOD_S)
        for k in range(n):
            t = t_s + k * PERIOD_S
            if writing and t >= self.next_write_s:
                count = (2**32 - 700 + round(travel_m(t) * TICKS_PER_M)) % 2**32
                self.pending = count
                self.arrival_s = t + self.rng.uniform(0.0, self.jitter_s)
                self.next_write_s += SCAN_S
            if self.arrival_s is not None and t >= self.arrival_s:
                self.link.write(22, [self.pending >> 16, self.pending & 0xFFFF])
                self.arrival_s = None
            out.append((t, travel_m(t), self.measure.conveyor_travel_at_m("belt", t)))
        return out


def test_a_count_written_every_scan_reads_as_the_belt_line_through_a_wrap(conveyors):
    line = _Line(conveyors)
    rows = line.run(2.0, 0.0, lambda t: SPEED_MPS * t)
    t, true, read = (np.array(c, dtype=float) for c in zip(*rows[250:], strict=True))
    # the count wrapped (2**32 -> 0) 700 ticks on, and the travel ran on through it
    assert line.link.encoder_registers[1][22] == 0 and read[-1] > 0.5
    # every period the belt moved on: no staircase between the 12 ms scans
    assert np.all(np.diff(read) > 0)
    # the line of the belt: its offset from the true travel (the writes' latency) steady
    offset = read - true
    assert np.ptp(offset) < 0.0015, np.ptp(offset)
    speed = np.diff(read[::50]) / np.diff(t[::50])
    assert np.all(np.abs(speed - SPEED_MPS) < 0.002), speed
    # the counts alone, stepped, are 3.6 mm apart
    steps = np.floor(true / (SPEED_MPS * SCAN_S))
    assert np.count_nonzero(np.diff(steps)) > 100


def test_a_belt_that_stops_reads_stopped_within_a_few_scans(conveyors):
    line = _Line(conveyors)
    stop_s = 1.0
    rows = line.run(1.5, 0.0, lambda t: SPEED_MPS * min(t, stop_s))
    t, _, read = (np.array(c, dtype=float) for c in zip(*rows[10:], strict=True))
    at_stop = read[t <= stop_s][-1]
    after = read[t >= stop_s + 0.1]
    # it ran on past the stop for at most 5 scans at the speed, then stood
    assert np.max(read) - at_stop < 5 * SCAN_S * SPEED_MPS
    assert np.ptp(after) < 0.0005
    assert abs(after[-1] - at_stop) < 0.002
    # stopped hard (from 0.3 m/s within a scan): logged, and still measured
    assert [(e, f["measured"]) for e, f in line.log.events] == [("plc_encoder_stale", True)]


def test_a_silent_plc_leaves_the_belt_unmeasured_until_it_writes_again(conveyors):
    line = _Line(conveyors)
    assert line.measure.conveyor_travel_at_m("belt", 0.0) is None  # no write yet

    def travel(t: float) -> float:
        return SPEED_MPS * t

    running = line.run(1.0, 0.0, travel)
    assert all(r[2] is not None for r in running[10:])
    silent = line.run(1.5, 1.0, travel, writing=False)
    # bridged at the speed for STALE_S past the last write, then not measured
    last_write_s = max(t for t, _, r in running if r is not None) - SCAN_S
    bridged = [r for t, _, r in silent if t < last_write_s + STALE_S]
    assert bridged and all(r is not None for r in bridged)
    assert all(r is None for t, _, r in silent if t > 1.0 + STALE_S + 0.002)
    assert [e for e, _ in line.log.events] == ["plc_encoder_stale"]
    assert "no write of registers 22-23" in line.log.events[0][1]["why"]
    line.next_write_s = 1.5
    back = line.run(2.0, 1.5, travel)
    assert all(r[2] is not None for r in back[10:])
    assert [e for e, _ in line.log.events] == ["plc_encoder_stale", "plc_encoder_back"]


def test_a_count_frozen_while_the_plc_writes_it_is_logged_and_reads_stopped(conveyors):
    line = _Line(conveyors)
    rows = line.run(1.5, 0.0, lambda t: SPEED_MPS * min(t, 1.0))
    assert all(r is not None for _, _, r in rows[10:])  # still measured: stopped
    assert [e for e, _ in line.log.events] == ["plc_encoder_stale"]
    why = line.log.events[0][1]["why"]
    ran = re.search(r"has not changed for ([0-9.]+) s after the belt ran at ([0-9.]+) m/s", why)
    assert ran is not None, why
    assert float(ran[1]) > STALE_S and abs(float(ran[2]) - SPEED_MPS) < 0.003


def test_the_engine_forgets_a_silent_belt_speed_and_keeps_its_travel(conveyors):
    line = _Line(conveyors)
    watch = BeltWatch(line.measure, conveyors, {"part_at_eye": "DI0"})
    q = np.zeros(6)

    def note(rows: list[Any]) -> None:
        for t, _, _ in rows:
            watch.note(RobotState(t, q, q, np.zeros(6), Safety.NORMAL))

    # the watch reads through the measurement: the runs below call it once a period too
    note(line.run(1.0, 0.0, lambda t: SPEED_MPS * t))
    view = watch.belts["belt"]
    speed = view.speed_mps()
    assert speed is not None and abs(speed - SPEED_MPS) < 0.003
    held = view.travel_m
    note(line.run(1.5, 1.0, lambda t: SPEED_MPS * t, writing=False))
    assert view.speed_mps() is None and view.travel_m is not None
    assert view.travel_m >= held  # bridged, then held


def test_an_unwrapped_count_is_the_same_signed_or_unsigned():
    signed, unsigned = WrappingCount(), WrappingCount()
    ticks = 2**31 - 5
    for step in (0, 3, 4, 10, -20, 7):
        ticks += step
        raw = ticks % 2**32
        assert signed.note(raw - 2**32 if raw >= 2**31 else raw) == unsigned.note(raw)
    assert unsigned.ticks == 4


def test_the_modbus_link_publishes_registers_20_29_whole_at_each_write_of_them():
    link = ModbusLink(FakeCell(tasks=plc_test_tasks()), clock=lambda: 0.0)
    assert link.encoder_registers[0] == 0
    link.write(0, [5])  # the heartbeat alone
    assert link.encoder_registers[0] == 0
    link.write(20, [0x1234, 0x5678])
    writes, regs = link.encoder_registers
    assert writes == 1 and (regs[20] << 16 | regs[21]) == 0x12345678
    link.write(20, list(range(20, 30)))  # 20-29 in one request: one write
    assert link.encoder_registers[0] == 2 and link.encoder_registers[1][28] == 28
