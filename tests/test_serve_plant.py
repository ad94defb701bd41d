"""`cellrunner serve` on the sim backend speaking the plant's language (SPEC 13): a generic
OPC UA client that knows only the standards' URIs and BrowseNames runs an ISA-95 job
order end to end over Basic256Sha256 SignAndEncrypt; ``Cell`` (SPEC 8) and Modbus
(SPEC 7) see the same job, unchanged."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.rig import (
    CELL,
    ENV,
    ROOT,
    TASK,
    add_opcua_user,
    free_port,
    modbus_client,
    start_serve,
    trusted_plc_certificate,
)
from tests.rig import OPCUA_PASSWORD as PASSWORD
from tests.rig import OPCUA_USER as USER

HOST = "127.0.0.7"


def companion_client(url: str, cert: Path, key: Path, *extra: str) -> dict:
    """tests/plc/companion_client.py in its own process, retried until serve listens."""
    argv = [
        sys.executable, str(ROOT / "tests" / "plc" / "companion_client.py"), "--url", url,
        "--cert", str(cert), "--key", str(key), "--user", USER, "--password", PASSWORD, *extra,
    ]  # fmt: skip
    deadline = time.monotonic() + 90
    while True:
        run = subprocess.run(argv, capture_output=True, text=True, timeout=170, env=ENV)
        lines = [line for line in run.stdout.splitlines() if line.startswith("{")]
        out = json.loads(lines[-1]) if lines else {"stderr": run.stderr[-2000:]}
        if out.get("connected") or time.monotonic() > deadline:
            return out
        time.sleep(1)


def test_a_job_order_runs_on_the_sim_and_modbus_and_cell_see_the_same_job(tmp_path: Path) -> None:
    url = f"opc.tcp://{HOST}:{free_port(HOST)}/cellrunner"
    port = free_port(HOST)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        CELL + "tasks: {1: tasks/t.yaml}\nplc:\n"
        f"  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 5.0}}\n"
        f"  opcua:\n    endpoint: {url}\n    users: secrets/users.yaml\n    pki: pki\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    add_opcua_user(tmp_path / "secrets" / "users.yaml")
    cert, key = trusted_plc_certificate(tmp_path)
    proc = start_serve(cell)
    try:
        out = companion_client(
            url, cert, key, "--scenario", "orders", "--task", "move_can", "--order", "WO-1",
            "--wait", "90", "--cell",
        )  # fmt: skip
        assert out.get("connected") and "error" not in out, out
        first = out["first"]
        assert first["states"] == [5, 1], first  # Ended / Completed
        assert first["data"]["ResultCode"] == 0 and first["data"]["CycleTime"] > 3
        assert "move_can" in out["task_programs"]
        assert out["again"] == 1 and out["again_response"]["data"] == first["data"]
        assert out["cell_last_job"] == first["data"]["JobId"]
        assert out["work_masters"] == [["move_can", []]]
        browse = companion_client(url, cert, key, "--scenario", "browse")
        assert browse["robotics"]["model"] == "UR10e", browse
        assert len(browse["robotics"]["positions"][0]) == 6
        assert browse["packml"]["states"][2] == ["Idle", 4]
        assert browse["packml"]["ProdProcessedCount"] == [1]
        regs = modbus_client(port, HOST).read_holding_registers(100, 14)
        # Modbus results are its own jobs' (SPEC 7); its counters count every job
        assert (regs[10] << 16) | regs[11] == 1 and (regs[12] << 16) | regs[13] == 0
        assert regs[2] == 4  # Idle
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    # serve again: the counters come from the journal, the order is answered from it
    proc = start_serve(cell)
    try:
        again = companion_client(
            url, cert, key, "--scenario", "orders", "--task", "move_can", "--order", "WO-1",
            "--wait", "30",
        )  # fmt: skip
        assert again.get("connected") and "error" not in again, again
        assert again["store_and_start"] == 1 and again["first"]["data"] == first["data"]
        browse = companion_client(url, cert, key, "--scenario", "browse")
        assert browse["packml"]["ProdProcessedCount"] == [1]  # no second job ran
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
