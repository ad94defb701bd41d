"""A production rig on loopback for reliability tests: ``cellrunner twin`` (the virtual UR
controller), ``cellrunner serve --backend ur`` against it (Modbus TCP, optionally OPC UA),
and an independent heartbeat probe, each in its own process.

Fixed UR ports: the twin binds 127.0.0.130-139 (this suite's range); Modbus and OPC UA
use free ports.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from pyModbusTCP.client import ModbusClient

from tests.conftest import ROOT
from tests.execution.test_dryrun import CELL

READY, JOB_ACK, BUSY, DONE, ERROR, REJECTED = 1, 2, 4, 8, 16, 512
PROTECTIVE_STOP, ESTOP = 64, 128
JOB_REQ, RESET = 1, 2
MODBUS_HOST = "127.0.0.130"

#: moves only: the twin behind `cellrunner twin` has no infeed, so a second pick would
#: find no part; a fault test wants every job to be able to end OK
TOUR = """
task: tour
steps:
  - move: home
  - move: {to: pick, offset: [0, 0, -0.15]}
  - move: {to: drop, offset: [0, 0, -0.15]}
  - move: home
on_protective_stop: {resume: true, max: 3}
"""


def free_port(host: str) -> int:
    import socket

    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def write_project(root: Path, *, opcua: bool = False) -> tuple[Path, int, str]:
    """cells/c.yaml + tasks/t.yaml under ``root``: (cell path, Modbus port, OPC UA url)."""
    (root / "cells").mkdir(exist_ok=True)
    (root / "tasks").mkdir(exist_ok=True)
    port = free_port(MODBUS_HOST)
    text = CELL + (
        "tasks: {1: tasks/t.yaml}\nplc:\n"
        f"  modbus: {{bind: {MODBUS_HOST}, port: {port}, heartbeat_timeout: 5.0}}\n"
    )
    url = ""
    if opcua:
        url = f"opc.tcp://{MODBUS_HOST}:{free_port(MODBUS_HOST)}/cellrunner"
        text += f"  opcua:\n    endpoint: {url}\n    security: [none]\n    users: secrets/users.yaml\n    pki: pki\n"
        users = root / "secrets" / "users.yaml"
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "users",
                "add",
                str(users),
                "line3",
                "--password-stdin",
            ],
            input="s3cret pass\n",
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=60,
        )
        assert r.returncode == 0, r.stderr
    (root / "cells" / "c.yaml").write_text(text)
    (root / "tasks" / "t.yaml").write_text(TOUR)
    return root / "cells" / "c.yaml", port, url


class Rig:
    """twin + serve + probe; ``with Rig(tmp_path, twin_host) as rig: ...``."""

    def __init__(self, root: Path, twin_host: str, *, opcua: bool = False):
        self.cell, self.port, self.opcua_url = write_project(root, opcua=opcua)
        self.twin_host = twin_host
        self.twin: subprocess.Popen | None = None
        self.serve: subprocess.Popen | None = None
        self.probe: subprocess.Popen | None = None
        self.watch: subprocess.Popen | None = None
        self.client: ModbusClient | None = None
        self.serve_log = root / "serve.log"
        self.beat = 0

    def __enter__(self) -> Rig:
        env = {**os.environ, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1"}
        self.twin = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "twin",
                str(self.cell),
                "--host",
                self.twin_host,
            ],
            cwd=ROOT,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        assert "virtual" in self.twin.stderr.readline()
        self._log = self.serve_log.open("w")
        self.serve = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "--log-format",
                "json",
                "serve",
                str(self.cell),
                "--backend",
                "ur",
                "--robot-host",
                self.twin_host,
            ],
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=self._log,
            env=env,
        )
        self.client = ModbusClient(host=MODBUS_HOST, port=self.port, timeout=2.0, auto_open=True)
        deadline = time.monotonic() + 60
        while not self.client.read_holding_registers(100, 14):
            assert self.serve.poll() is None, self.log_tail()
            assert time.monotonic() < deadline, "serve did not come up"
            time.sleep(0.2)
        return self

    def __exit__(self, *exc: object) -> None:
        for helper in (self.probe, self.watch):
            if helper is not None and helper.poll() is None:
                helper.kill()
        if self.serve is not None and self.serve.poll() is None:
            self.serve.send_signal(signal.SIGTERM)
            try:
                self.serve.wait(60)
            except subprocess.TimeoutExpired:
                self.serve.kill()
        self._log.close()
        if self.twin is not None:
            self.twin.terminate()
            try:
                self.twin.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                self.twin.kill()

    # ------------------------------------------------------------------ probe
    def start_probe(self) -> None:
        self.probe = subprocess.Popen(
            [
                sys.executable,
                str(ROOT / "tests" / "plc" / "heartbeat_probe.py"),
                "--host",
                MODBUS_HOST,
                "--port",
                str(self.port),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert json.loads(self.probe.stdout.readline()) == {"started": True}

    def start_watch(self) -> None:
        """An OPC UA client (its own process) reading Cell.State every 50 ms."""
        self.watch = subprocess.Popen(
            [
                sys.executable,
                str(ROOT / "tests" / "plc" / "opcua_watch.py"),
                "--url",
                self.opcua_url,
                "--user",
                "line3",
                "--password",
                "s3cret pass",
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert json.loads(self.watch.stdout.readline()) == {"started": True}

    def stop_watch(self) -> dict[str, Any]:
        out, _ = self.watch.communicate("", timeout=30)
        return json.loads(out.strip().splitlines()[-1])

    def stop_probe(self) -> dict[str, Any]:
        assert self.probe is not None
        out, _ = self.probe.communicate("", timeout=30)
        return json.loads(out.strip().splitlines()[-1])

    # ------------------------------------------------------------------ PLC
    def regs(self) -> list[int]:
        assert self.client is not None
        regs = self.client.read_holding_registers(100, 14)
        assert regs, "Modbus read failed"
        return regs

    def wait(self, predicate: Any, timeout_s: float, what: str) -> list[int]:
        deadline = time.monotonic() + timeout_s
        while True:
            assert self.serve is not None and self.serve.poll() is None, (
                f"serve died\n{self.log_tail()}"
            )
            regs = self.regs()
            if predicate(regs):
                return regs
            assert time.monotonic() < deadline, (
                f"{what} not seen within {timeout_s} s: {regs}\n{self.log_tail()}"
            )
            time.sleep(0.05)

    def trigger(self, job_id: int) -> list[int]:
        """Wait READY, request job ``job_id`` (task 1), wait for ACK+BUSY."""
        assert self.client is not None
        self.wait(lambda r: r[1] & READY, 60, "READY")
        self.client.write_multiple_registers(2, [job_id, 1])
        self.client.write_single_register(1, JOB_REQ)
        return self.wait(lambda r: r[1] & (JOB_ACK | ERROR), 5, "JOB_ACK")

    def finish(self, timeout_s: float = 90) -> list[int]:
        """Wait DONE or ERROR, then drop JOB_REQ; the result registers."""
        assert self.client is not None
        regs = self.wait(lambda r: r[1] & (DONE | ERROR), timeout_s, "DONE/ERROR")
        self.client.write_single_register(1, 0)
        return regs

    def reset(self) -> None:
        """RESET edges (Clear, Reset) every 2 s until READY, as an operator presses it
        again when the first press came before the controller saw the e-stop released."""
        assert self.client is not None
        for _ in range(15):
            self.client.write_single_register(1, 0)
            self.client.write_single_register(1, RESET)
            try:
                self.wait(lambda r: r[1] & READY, 2, "READY after RESET")
                break
            except AssertionError:
                continue
        self.wait(lambda r: r[1] & READY, 1, "READY after RESET")
        self.client.write_single_register(1, 0)

    def fault(self, command: str) -> str:
        from cellrunner.twin.server import FaultClient

        return FaultClient(self.twin_host).command(command)

    def log_tail(self, n: int = 3000) -> str:
        self._log.flush()
        return self.serve_log.read_text()[-n:]
