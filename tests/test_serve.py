"""`cellrunner serve` end to end: a separate process with the twin backend, driven over
Modbus TCP by an independent client (pyModbusTCP) exactly as SPEC section 7 says."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest
from pyModbusTCP.client import ModbusClient

from tests.execution.test_dryrun import CELL as DRYRUN_CELL
from tests.execution.test_dryrun import TASK
from tests.rig import (
    add_opcua_user,
    client_result,
    free_port,
    opcua_client,
    opcua_job,
    start_serve,
    trusted_plc_certificate,
)

READY, JOB_ACK, BUSY, DONE, ERROR, REJECTED = 1, 2, 4, 8, 16, 512
JOB_REQ = 1


@pytest.fixture
def project(tmp_path) -> tuple[Path, int]:
    host = "127.0.0.5"
    port = free_port(host)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = (
        DRYRUN_CELL
        + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {host}, port: {port}, heartbeat_timeout: 2.0}}\n"
    )
    (tmp_path / "cells" / "c.yaml").write_text(cell)
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    return tmp_path / "cells" / "c.yaml", port


def start(cell: Path) -> subprocess.Popen[str]:
    return start_serve(cell)


def connect(port: int, timeout_s: float = 60.0) -> ModbusClient:
    client = ModbusClient(host="127.0.0.5", port=port, timeout=2.0, auto_open=True)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if client.read_holding_registers(100, 14):
            return client
        time.sleep(0.2)
    raise AssertionError("serve did not come up")


def wait(client: ModbusClient, mask: int, timeout_s: float, beat: list) -> list[int]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        beat[0] = (beat[0] + 1) % 65536
        client.write_single_register(0, beat[0])  # the PLC heartbeat keeps moving
        regs = client.read_holding_registers(100, 14)
        if regs and regs[1] & mask == mask:
            return regs
        time.sleep(0.05)
    raise AssertionError(
        f"status bits {mask:#x} not seen within {timeout_s} s: {client.read_holding_registers(100, 14)}"
    )


def job(client, job_id: int, task: int, params: list[int], beat) -> list[int]:
    wait(client, READY, 30, beat)
    client.write_multiple_registers(2, [job_id, task, *params])
    client.write_single_register(1, JOB_REQ)
    regs = wait(client, JOB_ACK, 5, beat)
    assert regs[3] == job_id  # echo
    regs = wait(client, BUSY, 1, beat) if not regs[1] & (DONE | ERROR) else regs
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        regs = wait(client, 0, 5, beat)
        if regs[1] & (DONE | ERROR):
            break
    client.write_single_register(1, 0)
    return regs


def test_serve_runs_plc_jobs_and_stops_on_sigterm(project):
    cell, port = project
    proc = start(cell)
    try:
        client = connect(port)
        beat = [0]
        regs = job(client, 41, 1, [], beat)
        assert regs[1] & DONE and not regs[1] & ERROR, regs
        assert (regs[4], regs[5]) == (41, 0)  # result job id, OK
        cycle_ms = (regs[8] << 16) | regs[9]
        assert 3000 < cycle_ms < 20000
        assert (regs[10] << 16) | regs[11] == 1  # parts processed
        wait(client, READY, 10, beat)
        # rejects: unknown task 7
        client.write_multiple_registers(2, [42, 7])
        client.write_single_register(1, JOB_REQ)
        regs = wait(client, ERROR | REJECTED, 5, beat)
        assert regs[5] == 10
        client.write_single_register(1, 0)
        wait(client, READY, 10, beat)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    assert '"event": "stopped"' in err


def test_restart_mid_job_reports_107(project):
    cell, port = project
    proc = start(cell)
    beat = [0]
    try:
        client = connect(port)
        wait(client, READY, 30, beat)
        client.write_multiple_registers(2, [77, 1])
        client.write_single_register(1, JOB_REQ)
        wait(client, JOB_ACK | BUSY, 5, beat)
        time.sleep(1.0)
    finally:
        proc.kill()  # no chance to close the job
        proc.communicate(timeout=30)
    proc = start(cell)
    try:
        client = connect(port)
        regs = client.read_holding_registers(100, 14)
        assert (regs[4], regs[5]) == (77, 107), regs
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    assert proc.returncode == 0


def test_serve_over_opcua_with_encryption_and_a_user(tmp_path):
    """OPC UA through serve: Basic256Sha256 SignAndEncrypt, a user from `users add`, a
    trusted client certificate; StartJob runs a real twin job and the event arrives."""
    port = free_port("127.0.0.6")
    url = f"opc.tcp://127.0.0.6:{port}/cellrunner"
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell_path = tmp_path / "cells" / "c.yaml"
    cell_path.write_text(
        DRYRUN_CELL + "tasks: {1: tasks/t.yaml}\nplc:\n  opcua:\n"
        f"    endpoint: {url}\n    users: secrets/users.yaml\n    pki: pki\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    add_opcua_user(tmp_path / "secrets" / "users.yaml")
    cert, key = trusted_plc_certificate(tmp_path)
    proc = start(cell_path)
    try:
        result = opcua_job(url, cert, key, "move_can")
        assert result["return_code"] == 0 and result["job_id"]
        assert [e["ResultCode"] for e in result["events"]] == [0]
        assert result["events"][0]["JobId"] == result["job_id"]
        assert result["last_result"] == 0 and result["cycle_time"] > 3
        wrong = opcua_client(url, cert, key, "--scenario", "connect", "--password", "wrong")
        assert client_result(wrong, 60).get("connected") is False
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    assert proc.returncode == 0


def test_json_logs_carry_no_raw_library_lines(project):
    """Garbage on the Modbus port makes pymodbus complain; with --log-format json its
    complaints are JSON lines like every other event."""
    cell, port = project
    proc = start(cell)
    try:
        connect(port)
        for payload in (b"\x00\x01\x00\x00\x00\x02\x01\x63", b"\xff" * 300):
            with socket.create_connection(("127.0.0.5", port), timeout=5) as sock:
                sock.sendall(payload)
                time.sleep(0.3)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    lines = [line for line in err.splitlines() if line.strip()]
    assert any("pymodbus" in line for line in lines), err[-2000:]
    for line in lines:
        assert isinstance(json.loads(line), dict), line
