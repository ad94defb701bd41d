"""Fixtures: PLC servers on loopback backed by a FakeCell, and PLC clients in processes."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cellrunner.plc.fake import FakeCell, FakeParam, FakeTask
from cellrunner.plc.service import PlcService

HERE = Path(__file__).parent
#: the OPC UA user the PLC tests log in as
USER, PASSWORD = "line3-plc", "correct horse battery"
REPO = HERE.parent.parent
HEARTBEAT_TIMEOUT_S = 0.6


def child_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return env


class PlcProcess:
    """A Modbus client in its own process, driven line by line (see modbus_repl.py)."""

    def __init__(self, lib: str, host: str, port: int) -> None:
        self.lib = lib
        self.proc = subprocess.Popen(
            [
                sys.executable,
                str(HERE / "modbus_repl.py"),
                "--lib",
                lib,
                "--host",
                host,
                "--port",
                str(port),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=child_env(),
        )
        hello = self._readline(20.0)
        assert hello.get("ready"), hello

    def _readline(self, timeout_s: float) -> dict[str, Any]:
        assert self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout_s)
        if not ready:
            raise TimeoutError(f"{self.lib} client gave no answer within {timeout_s} s")
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"{self.lib} client exited with {self.proc.poll()}")
        return json.loads(line)

    def call(self, op: str, timeout_s: float = 10.0, **kw: Any) -> dict[str, Any]:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": op, **kw}) + "\n")
        self.proc.stdin.flush()
        return self._readline(timeout_s + float(kw.get("timeout", 0)))

    def read(self, addr: int, count: int = 1) -> list[int]:
        reply = self.call("read", addr=addr, count=count)
        assert reply["ok"], reply
        return reply["values"]

    def write(self, addr: int, values: list[int]) -> dict[str, Any]:
        return self.call("write", addr=addr, values=values)

    def wait_bits(
        self, mask: int, value: int, timeout: float = 5.0, addr: int = 101
    ) -> dict[str, Any]:
        return self.call("wait", addr=addr, mask=mask, value=value, timeout=timeout)

    def close(self) -> None:
        try:
            if self.proc.poll() is None and self.proc.stdin is not None:
                self.proc.stdin.write(json.dumps({"op": "quit"}) + "\n")
                self.proc.stdin.flush()
            self.proc.wait(timeout=5)
        except Exception:
            self.proc.kill()
            self.proc.wait(timeout=5)
        finally:
            for stream in (self.proc.stdin, self.proc.stdout):
                if stream is not None:
                    stream.close()


def plc_test_tasks() -> list[FakeTask]:
    return [
        FakeTask(
            1,
            "pick_place",
            (FakeParam("slot", "int", 0, 11, 0), FakeParam("depth", "int", -50, 50, 0)),
        ),
        FakeTask(2, "home", (), (0.02,)),
        FakeTask(3, "slow", (), (0.4, 0.4, 0.4)),
    ]


@pytest.fixture
def cell() -> Iterator[FakeCell]:
    fake = FakeCell(tasks=plc_test_tasks(), parts_processed=70_000, parts_defective=65_535)
    with fake:
        yield fake


@pytest.fixture
def modbus_service(cell: FakeCell) -> Iterator[PlcService]:
    config = {"modbus": {"bind": "127.0.0.1", "port": 0, "heartbeat_timeout": HEARTBEAT_TIMEOUT_S}}
    service = PlcService(cell, config)
    service.start()
    try:
        yield service
    finally:
        service.stop()


@pytest.fixture(params=["pymodbus", "pyModbusTCP"])
def plc(request: pytest.FixtureRequest, modbus_service: PlcService) -> Iterator[PlcProcess]:
    host, port = modbus_service.modbus_address or ("127.0.0.1", 0)
    client = PlcProcess(request.param, host, port)
    try:
        yield client
    finally:
        client.close()
