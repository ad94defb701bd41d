"""Start a virtual UR controller in its own process, on its own loopback address.

Every twin gets a fresh 127.x.y.z address (the whole 127/8 is loopback on Linux), so
tests never clash on the fixed UR ports. :class:`TwinProcess` also speaks the fault
channel.
"""

from __future__ import annotations

import itertools
import json
import multiprocessing
import os
import socket
import time
from typing import Any

_hosts = itertools.count(2)


def fresh_host() -> str:
    """A loopback address no other twin of this test process uses."""
    n = next(_hosts)
    return f"127.{100 + os.getpid() % 100}.{n // 250}.{n % 250 + 2}"


def _serve(robot: str, host: str, stop: Any, ready: Any, config: dict[str, Any]) -> None:
    import threading

    from cellrunner.twin.server import run_twin

    parent = os.getppid()

    def orphan_watch() -> None:  # never outlive the test process (killed, timed out)
        while not stop.wait(0.5):
            if os.getppid() != parent:
                stop.set()

    threading.Thread(target=orphan_watch, daemon=True).start()
    run_twin(robot, host=host, stop_event=stop, ready=ready, **config)


class TwinProcess:
    """A twin in a spawned process; ``with TwinProcess("ur5e") as twin: ...``."""

    def __init__(self, robot: str = "ur5e", host: str | None = None, **config: Any):
        self.robot = robot
        self.host = host or fresh_host()
        self.config = config
        ctx = multiprocessing.get_context("spawn")
        self._stop = ctx.Event()
        self._ready = ctx.Event()
        self._process = ctx.Process(
            target=_serve, args=(robot, self.host, self._stop, self._ready, config), daemon=True
        )

    def __enter__(self) -> TwinProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        self._process.start()
        if not self._ready.wait(15.0):
            self.stop()
            raise RuntimeError(f"twin on {self.host} did not start within 15 s")

    def stop(self) -> None:
        self._stop.set()
        self._process.join(5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(2.0)

    def fault(self, command: str, timeout_s: float = 3.0) -> str:
        """Send one fault-channel command; returns the text after ``ok`` (raises on error)."""
        from cellrunner.twin.server import FaultClient

        return FaultClient(self.host, timeout_s=timeout_s).command(command)

    def state(self) -> dict[str, Any]:
        return json.loads(self.fault("state"))


def wait_until(predicate: Any, timeout_s: float, interval_s: float = 0.01) -> bool:
    """Poll ``predicate`` until true or ``timeout_s`` passed; returns its last value."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value or time.monotonic() > deadline:
            return bool(value)
        time.sleep(interval_s)


class Dashboard:
    """A raw dashboard connection (exact reply strings, no client library in between)."""

    def __init__(self, host: str, timeout_s: float = 3.0):
        self.sock = socket.create_connection((host, 29999), timeout=timeout_s)
        self.file = self.sock.makefile("rw", newline="\n")
        self.greeting = self.file.readline().rstrip("\n")

    def ask(self, command: str) -> str:
        self.file.write(command + "\n")
        self.file.flush()
        return self.file.readline().rstrip("\n")

    def close(self) -> None:
        self.file.close()
        self.sock.close()
