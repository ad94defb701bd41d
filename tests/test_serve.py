"""`cellrunner serve` end to end: a separate process with the twin backend, driven over
Modbus TCP by an independent client (pyModbusTCP) exactly as SPEC section 7 says."""

from __future__ import annotations

import json
import signal
import socket
import time
from pathlib import Path

import pytest

from tests.rig import (
    BUSY,
    CELL,
    DONE,
    ERROR,
    JOB_ACK,
    JOB_REQ,
    READY,
    REJECTED,
    TASK,
    add_opcua_user,
    client_result,
    free_port,
    modbus_client,
    opcua_client,
    opcua_job,
    plc_job,
    start_serve,
    trusted_plc_certificate,
    wait_bits,
)

HOST = "127.0.0.5"


@pytest.fixture
def project(tmp_path) -> tuple[Path, int]:
    host = HOST
    port = free_port(host)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = (
        CELL
        + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {host}, port: {port}, heartbeat_timeout: 2.0}}\n"
    )
    (tmp_path / "cells" / "c.yaml").write_text(cell)
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    return tmp_path / "cells" / "c.yaml", port


def test_serve_runs_plc_jobs_and_stops_on_sigterm(project):
    cell, port = project
    proc = start_serve(cell)
    try:
        client = modbus_client(port, HOST)
        beat = [0]
        regs = plc_job(client, 41, 1, [], beat)
        assert regs[1] & DONE and not regs[1] & ERROR, regs
        assert (regs[4], regs[5]) == (41, 0)  # result job id, OK
        cycle_ms = (regs[8] << 16) | regs[9]
        assert 3000 < cycle_ms < 20000
        assert (regs[10] << 16) | regs[11] == 1  # parts processed
        wait_bits(client, READY, 10, beat)
        # rejects: unknown task 7
        client.write_multiple_registers(2, [42, 7])
        client.write_single_register(1, JOB_REQ)
        regs = wait_bits(client, ERROR | REJECTED, 5, beat)
        assert regs[5] == 10
        client.write_single_register(1, 0)
        wait_bits(client, READY, 10, beat)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    assert '"event": "stopped"' in err


def test_restart_mid_job_reports_107(project):
    cell, port = project
    proc = start_serve(cell)
    beat = [0]
    try:
        client = modbus_client(port, HOST)
        wait_bits(client, READY, 30, beat)
        client.write_multiple_registers(2, [77, 1])
        client.write_single_register(1, JOB_REQ)
        wait_bits(client, JOB_ACK | BUSY, 5, beat)
        time.sleep(1.0)
    finally:
        proc.kill()  # no chance to close the job
        proc.communicate(timeout=30)
    proc = start_serve(cell)
    try:
        client = modbus_client(port, HOST)
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
        CELL + "tasks: {1: tasks/t.yaml}\nplc:\n  opcua:\n"
        f"    endpoint: {url}\n    users: secrets/users.yaml\n    pki: pki\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    add_opcua_user(tmp_path / "secrets" / "users.yaml")
    cert, key = trusted_plc_certificate(tmp_path)
    proc = start_serve(cell_path)
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
    proc = start_serve(cell)
    try:
        modbus_client(port, HOST)
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
