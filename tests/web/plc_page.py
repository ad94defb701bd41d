"""`cellrunner serve` with its status page, and a Modbus PLC that keeps its heartbeat
moving, for the browser tests."""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from pyModbusTCP.client import ModbusClient

from tests.rig import start_serve

#: status bits (SPEC 8)
READY, JOB_ACK, DONE, ERROR = 1, 2, 8, 16

#: status bit: the arm waits for an obstacle in the watched zone
OBSTRUCTED = 1 << 10
#: on the path from the job's start for 4 s (appearing under a moving arm, under load the
#: real-time latency could let the arm stop over it and hide it from the camera)
TOTE = "{name: tote, box: {size: [0.2, 0.14, 0.1]}, pose: {xyz: [0.52, -0.24, 1.1]}, appear: 0.0, leave: 4.0}"


class Plc:
    """A PLC over Modbus TCP that keeps its heartbeat moving."""

    def __init__(self, host: str, port: int):
        self.client = ModbusClient(host=host, port=port, timeout=2.0, auto_open=True)
        self.beat = 0

    def poll(self) -> list[int] | None:
        self.beat = (self.beat + 1) % 65536
        self.client.write_single_register(0, self.beat)
        return self.client.read_holding_registers(100, 14)

    def wait(self, mask: int, timeout_s: float) -> list[int]:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            regs = self.poll()
            if regs and regs[1] & mask == mask:
                return regs
            time.sleep(0.05)
        raise AssertionError(f"status bits {mask:#x} not seen within {timeout_s} s")


@contextlib.contextmanager
def heartbeat(host: str, port: int, period_s: float = 0.1, max_s: float = 300.0) -> Iterator[None]:
    """The PLC's heartbeat moved by a task of its own (its own connection and thread, as
    a PLC runs it), for tests whose browser calls may take longer than the heartbeat
    timeout (a screenshot of a WebGL page drawn in software on a loaded machine)."""
    client = ModbusClient(host=host, port=port, timeout=2.0, auto_open=True)
    stop = threading.Event()

    def beat() -> None:
        value, deadline = 40000, time.monotonic() + max_s
        while not stop.wait(period_s) and time.monotonic() < deadline:
            value = value + 1 if value < 65535 else 40000
            client.write_single_register(0, value)

    thread = threading.Thread(target=beat, name="plc-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=5)
        client.close()


@contextlib.contextmanager
def serve_with_page(
    cell: Path, host: str, modbus_port: int, http_port: int
) -> Iterator[tuple[str, Plc]]:
    """``serve`` of ``cell`` on the twin with its page at ``host:http_port``, once its
    Modbus server answers: (the page's URL, a PLC); stopped with SIGTERM after, which
    must end it with 0."""
    proc = start_serve(cell, "--backend", "sim", "--http", f"{host}:{http_port}")
    try:
        plc = Plc(host, modbus_port)
        deadline = time.monotonic() + 90
        while not plc.poll():
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()[-2000:]
            time.sleep(0.2)
        yield f"http://{host}:{http_port}/", plc
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]


@contextlib.contextmanager
def serving_the_tote(tmp_path: Path, host: str) -> Iterator[object]:
    """`serve` of the watched demo cell on the twin with its page, a tote only the depth
    camera sees on the job's path for 4 s (the task waits up to 10 s, no replanning), and
    a PLC keeping its heartbeat; what :func:`serve_with_page` yields."""
    from tests.conftest import ROOT
    from tests.rig import free_port

    modbus_port, http_port = free_port(host), free_port(host)
    text = (ROOT / "cells" / "watched_ur5e.yaml").read_text()
    text = text.replace(
        "sim:\n  depth_noise: 0.002\n", f"sim:\n  depth_noise: 0.002\n  intruders:\n    - {TOTE}\n"
    )
    text = text.replace("tasks/pick_place_watched.yaml", "tasks/pick_place.yaml")
    text = text.replace("tasks/", f"{ROOT}/tasks/").replace("var/", f"{tmp_path}/")
    text = text.replace("bind: 127.0.0.1, port: 1503", f"bind: {host}, port: {modbus_port}")
    text = text.split("  opcua:")[0] + f"journal: {tmp_path}/jobs.sqlite\n"
    cell = tmp_path / "watched.yaml"
    cell.write_text(text)
    with (
        serve_with_page(cell, host, modbus_port, http_port) as served,
        heartbeat(host, modbus_port),
    ):
        yield served
