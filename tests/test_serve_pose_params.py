"""The vision pick under `cellrunner serve`: the PLC supplies the part's pose with the
job, as six int16 registers over Modbus (0.1 mm, 0.01 deg; the param window is 4-19) and
as {"xyz", "rpy"} JSON over OPC UA (SPEC section 11); the journal keeps what it got."""

from __future__ import annotations

import json
import re
import shutil
import signal
import sqlite3
import time
from pathlib import Path

import pytest
from pyModbusTCP.client import ModbusClient

from cellrunner.plc.param_registers import decode_params, encode_pose, from_int16
from tests.conftest import ROOT
from tests.rig import (
    DONE,
    ERROR,
    JOB_REQ,
    READY,
    REJECTED,
    add_opcua_user,
    free_port,
    opcua_job,
    start_serve,
    trusted_plc_certificate,
    wait_bits,
)

HOST = "127.0.0.122"
SEEN = {"xyz": [0.03, -0.02, 0.0], "rpy": [0.0, 0.0, 20.0]}  # where the twin's part lies


def test_pose_registers_round_trip_and_the_window_layout():
    words = encode_pose(SEEN["xyz"], SEEN["rpy"])
    assert words == [300, from_int16(-200), 0, 0, 0, 2000]
    layout = [("part_pose", "pose", None), ("settle", "float", "ms"), ("n", "int", None)]
    got = decode_params(layout, [*words, 150, from_int16(-3), *[0] * 8])
    assert got == {
        "part_pose": {"xyz": [0.03, -0.02, 0.0], "rpy": [0.0, 0.0, 20.0]},
        "settle": 0.15,  # an SI number (s), from register to step
        "n": -3,
    }
    with pytest.raises(ValueError, match="pose value 40000 counts does not fit an int16 register"):
        encode_pose([4.0, 0, 0], [0, 0, 0])


def _project(tmp_path: Path, plc: str) -> Path:
    for folder in ("cells", "tasks"):
        shutil.copytree(ROOT / folder, tmp_path / folder)
    cell = tmp_path / "cells" / "vision_pick_ur10e.yaml"
    text = re.sub(r"plc:\n(  .*\n)+", plc, cell.read_text())
    cell.write_text(
        text.replace("journal: var/vision-jobs.sqlite", f"journal: {tmp_path}/jobs.sqlite")
    )
    return cell


def _job(client: ModbusClient, job_id: int, params: list[int], beat: list) -> list[int]:
    wait_bits(client, READY, 60, beat)
    client.write_multiple_registers(2, [job_id, 1, *params])
    client.write_single_register(1, JOB_REQ)
    deadline = time.monotonic() + 120
    regs: list[int] = []
    while time.monotonic() < deadline:
        regs = wait_bits(client, 0, 5, beat)
        if regs[1] & (DONE | ERROR) and regs[4] == job_id:
            break
    client.write_single_register(1, 0)
    return regs


def test_vision_pick_with_the_pose_in_modbus_registers(tmp_path):
    port = free_port(HOST)
    cell = _project(
        tmp_path, f"plc:\n  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 2.0}}\n"
    )
    proc = start_serve(cell)
    beat = [0]
    try:
        client = ModbusClient(host=HOST, port=port, timeout=2.0, auto_open=True)
        deadline = time.monotonic() + 90
        while not client.read_holding_registers(100, 14) and time.monotonic() < deadline:
            time.sleep(0.2)
        regs = _job(client, 51, [*encode_pose(SEEN["xyz"], SEEN["rpy"]), 120], beat)
        assert (regs[4], regs[5]) == (51, 0), regs  # result job id, OK
        # a pose outside the param's box is refused with 11 (bad params)
        regs = _job(client, 52, encode_pose([0.2, 0, 0], [0, 0, 0]), beat)
        assert regs[1] & REJECTED and (regs[4], regs[5]) == (52, 11), regs
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    with sqlite3.connect(tmp_path / "jobs.sqlite") as db:
        rows = db.execute("select params from jobs order by rowid").fetchall()
    assert json.loads(rows[0][0]) == {"part_pose": SEEN, "settle": 0.12}


def test_vision_pick_with_the_pose_as_opcua_json(tmp_path):
    port = free_port(HOST)
    url = f"opc.tcp://{HOST}:{port}/cellrunner"
    cell = _project(
        tmp_path,
        f"plc:\n  opcua:\n    endpoint: {url}\n    users: secrets/users.yaml\n    pki: pki\n",
    )
    add_opcua_user(tmp_path / "secrets" / "users.yaml")
    cert, key = trusted_plc_certificate(tmp_path)
    proc = start_serve(cell)
    try:
        params = json.dumps({"part_pose": SEEN, "settle": "80 ms"})
        # serve warms up its planning before it listens
        result = opcua_job(url, cert, key, "vision_pick", "--params", params, listen_timeout_s=150)
        assert result["return_code"] == 0 and result["job_id"]
        assert [e["ResultCode"] for e in result["events"]] == [0]
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    with sqlite3.connect(tmp_path / "jobs.sqlite") as db:
        rows = db.execute("select params from jobs order by rowid").fetchall()
    assert json.loads(rows[0][0]) == {"part_pose": SEEN, "settle": 0.08}
