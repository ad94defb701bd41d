"""A belt whose encoder the PLC counts (``source: plc``, SPEC section 13) on the arm,
through the unmodified ur_rtde client against ``cellrunner twin`` of the same cell:

- ``run --backend ur`` has no PLC: the belt is not measured there, and its ``track`` step
  is refused with 103 naming why, the arm never set onto the belt;
- ``serve --backend ur`` reads the PLC's registers: a PLC on loopback runs the job with
  the handshake (pyModbusTCP) while its encoder task (a pymodbus client) writes the
  belt's count into registers 20-21 every 10 ms. The count is the twin's own belt travel,
  asked of its fault channel (``belt belt travel``) each scan: the belt the PLC counts is
  the one that carries the block."""

from __future__ import annotations

import json
import signal
import threading
import time
from pathlib import Path

import numpy as np
from pymodbus.client import ModbusTcpClient

from tests.plc_belt_rig import plc_belt_project
from tests.rig import (
    DONE,
    ERROR,
    JOB_ACK,
    JOB_REQ,
    READY,
    fault,
    free_port,
    modbus_client,
    run_ur,
    start_serve,
    twin,
    wait_bits,
)

HOST, SERVE_HOST = "127.0.0.174", "127.0.0.175"
TRAY_PART_XYZ = (0.35, 0.55, 0.826)  # the block's centre once placed (the grip frame)


def _cell(tmp_path: Path, plc: str = "") -> tuple[Path, Path]:
    return plc_belt_project(tmp_path, extra=plc)


def test_run_on_the_arm_refuses_to_track_a_belt_the_plc_counts(tmp_path: Path) -> None:
    cell, task = _cell(tmp_path)
    with twin(cell, HOST):
        out = run_ur(cell, task, HOST)
    assert (out["backend"], out["result_code"]) == ("ur", 103), out["result_text"]
    assert "cannot measure the belt" in out["result_text"], out["result_text"]
    steps = out["steps"]
    # the move over the belt ran; the track step is the one refused, nothing after it ran
    assert steps[0]["status"] == "ok" and steps[1]["status"] != "ok", steps[:3]
    assert all(s["status"] != "ok" for s in steps[1:]), steps


def _encoder_task(port: int, stop: threading.Event) -> None:
    """The PLC's encoder task: the twin's belt count into registers 20-21 every 10 ms."""
    client = ModbusTcpClient(SERVE_HOST, port=port, timeout=2)
    deadline = time.monotonic() + 300
    try:
        while not stop.is_set() and time.monotonic() < deadline:
            travel = float(fault(HOST, "belt belt travel"))
            count = round(travel * 4000) % 2**32
            if client.connected or client.connect():
                client.write_registers(20, [count >> 16, count & 0xFFFF])
            time.sleep(0.01)
    finally:
        client.close()


def test_serve_on_the_arm_tracks_a_belt_the_plc_counts(tmp_path: Path) -> None:
    port = free_port(SERVE_HOST)
    plc = f"plc:\n  modbus: {{bind: {SERVE_HOST}, port: {port}, heartbeat_timeout: 2.0}}\n"
    cell, _ = _cell(tmp_path, plc)
    stop = threading.Event()
    encoder = threading.Thread(target=_encoder_task, args=(port, stop), daemon=True)
    with twin(cell, HOST):
        fault(HOST, "belt belt speed 0")  # the line held until the arm waits over it
        proc = start_serve(cell, "--backend", "ur", "--robot-host", HOST)
        try:
            client = modbus_client(port, SERVE_HOST)
            encoder.start()
            beat = [0]
            wait_bits(client, READY, 30, beat)
            client.write_multiple_registers(2, [1, 1])
            client.write_single_register(1, JOB_REQ)
            regs = wait_bits(client, JOB_ACK, 5, beat)
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and regs[6] < 2 and not regs[1] & (DONE | ERROR):
                regs = wait_bits(client, 0, 5, beat)
            time.sleep(0.5)  # the arm stands over the belt
            fault(HOST, "belt belt speed 0.3")
            while time.monotonic() < deadline and not regs[1] & (DONE | ERROR):
                regs = wait_bits(client, 0, 5, beat)
                time.sleep(0.05)
            client.write_single_register(1, 0)
            parts = json.loads(fault(HOST, "parts"))
        finally:
            stop.set()
            encoder.join(5)
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    ends = [json.loads(line).get("message") for line in err.splitlines() if "job_end" in line]
    assert regs[1] & DONE and regs[5] == 0, (regs, ends)
    placed = [
        n for n, xyz in parts.items() if np.linalg.norm(np.subtract(xyz, TRAY_PART_XYZ)) < 0.01
    ]
    assert len(placed) == 1, parts
