"""``serve --backend sim --faults FILE`` (issue 37, a soak's faults besides kill -9): the
twin makes the drawn faults happen while a PLC (pyModbusTCP, its own heartbeat, over
loopback) runs jobs. An e-stop on every job: each ends ERROR 101, the journal has the same
result, the operator's release and the PLC's RESET bring the cell back to READY for the
next. A faults file serve cannot make happen, or a real arm: one line, exit 2."""

from __future__ import annotations

import signal
import sqlite3
import time

from cellrunner.model.codes import ResultCode
from tests.conftest import ROOT
from tests.rig import (
    DONE,
    ERROR,
    JOB_ACK,
    JOB_REQ,
    READY,
    RESET,
    cli,
    free_port,
    modbus_client,
    start_serve,
    wait_bits,
)

TOUR = """task: tour
steps:
  - move: {to: pallet, offset: [0, 0, -0.15]}
  - move: home
"""


def soak_cell(tmp_path, port: int):
    text = (ROOT / "cells" / "demo_ur5e.yaml").read_text().split("\ntasks:")[0]
    text += (
        "\ntasks: {1: tasks/tour.yaml}\n"
        f"plc:\n  modbus: {{bind: 127.0.0.1, port: {port}, heartbeat_timeout: 2.0}}\n"
        f"journal: {tmp_path / 'jobs.sqlite'}\n"
    )
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "tour.yaml").write_text(TOUR)
    cell = tmp_path / "cell.yaml"
    cell.write_text(text)
    return cell


def test_estops_drawn_on_every_job_end_each_with_101_and_the_plc_resets(tmp_path):
    port = free_port()
    cell = soak_cell(tmp_path, port)
    faults = tmp_path / "faults.yaml"
    faults.write_text("{estop: 1.0}\n")
    proc = start_serve(cell, "--backend", "sim", "--sim-fast", "--faults", str(faults))
    beat = [0]
    codes = []
    try:
        client = modbus_client(port, "127.0.0.1", timeout_s=120)
        for job_id in (1, 2):
            deadline = time.monotonic() + 60  # READY, pressing RESET as a PLC program does
            while True:
                regs = wait_bits(client, 0, 5, beat)
                if regs[1] & READY:
                    break
                assert time.monotonic() < deadline, regs
                client.write_single_register(1, RESET)
                wait_bits(client, 0, 0.3, beat)
                client.write_single_register(1, 0)
            client.write_multiple_registers(2, [job_id, 1])
            client.write_single_register(1, JOB_REQ)
            wait_bits(client, JOB_ACK, 10, beat)
            deadline = time.monotonic() + 120
            regs = wait_bits(client, 0, 5, beat)
            while not regs[1] & (DONE | ERROR):
                assert time.monotonic() < deadline, regs
                regs = wait_bits(client, 0, 5, beat)
            assert regs[4] == job_id, regs
            codes.append((regs[1] & ERROR != 0, regs[5]))
            client.write_single_register(1, 0)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    assert codes == [(True, int(ResultCode.ESTOP))] * 2, codes
    db = sqlite3.connect(tmp_path / "jobs.sqlite")
    rows = db.execute("SELECT client_job_id, result_code FROM jobs ORDER BY started_at").fetchall()
    db.close()
    assert rows == [("1", 101), ("2", 101)], rows
    assert err.count('"fault_injected"') == 2 and err.count('"estop_released"') >= 1, err[-3000:]


def test_faults_serve_cannot_make_happen_are_one_line_exit_2(tmp_path):
    cell = soak_cell(tmp_path, free_port())
    faults = tmp_path / "faults.yaml"
    faults.write_text("{robot_disconnect: 0.01}\n")
    r = cli("serve", str(cell), "--backend", "sim", "--faults", str(faults), timeout_s=120)
    assert r.returncode == 2, r.stderr
    [line] = r.stderr.strip().splitlines()
    assert line.startswith(f"{faults}:1:") and "robot_disconnect" in line and "estop" in line
    faults.write_text("{estop: 0.01}\n")
    r = cli("serve", str(cell), "--backend", "ur", "--faults", str(faults), timeout_s=120)
    assert r.returncode == 2 and "--backend sim" in r.stderr, r.stderr
    faults.write_text("{estop: 2}\n")
    r = cli("serve", str(cell), "--backend", "sim", "--faults", str(faults), timeout_s=120)
    assert r.returncode == 2 and f"{faults}:1:" in r.stderr, r.stderr
