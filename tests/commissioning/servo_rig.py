"""`cellrunner jog --input udp:PORT` driven by a program that is not cellrunner
(tests/commissioning/udp_sender.py), and the arm measured through the unmodified ur_rtde
receive client: the servo tests' rig."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from tests.conftest import ROOT
from tests.rig import CLI, ENV

#: a loopback address of this process's own: several checkouts run these tests at once
HOST = f"127.26.{os.getpid() % 250 + 1}.1"
SENDER = ROOT / "tests" / "commissioning" / "udp_sender.py"


class Recorder:
    """TCP positions (base frame, m) read through ur_rtde at the controller rate, with
    their time.monotonic() stamps, from a thread."""

    def __init__(self, host: str) -> None:
        import rtde_receive

        self.receive = rtde_receive.RTDEReceiveInterface(host, 500.0, ["actual_TCP_pose"])
        self.samples: list[tuple[float, list[float]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        deadline = time.monotonic() + 120
        while not self._stop.is_set() and time.monotonic() < deadline:
            self.samples.append((time.monotonic(), self.receive.getActualTCPPose()[:3]))
            time.sleep(0.001)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.receive.disconnect()

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        t = np.array([s[0] for s in self.samples])
        return t, np.array([s[1] for s in self.samples])


@contextlib.contextmanager
def jog_udp(cell: Path, port: int) -> Iterator[tuple[subprocess.Popen[str], list[str]]]:
    proc = subprocess.Popen(
        [*CLI, "jog", str(cell), "--robot-host", HOST, "--input", f"udp:{port}"],
        cwd=ROOT,
        env=ENV,
        stdin=subprocess.DEVNULL,  # no terminal: jog works without one for this input
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    assert proc.stdout is not None
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()  # type: ignore[arg-type]
    deadline = time.monotonic() + 60
    while not any("no datagram yet" in line for line in lines):
        assert proc.poll() is None, "".join(lines)
        assert time.monotonic() < deadline, "".join(lines)
        time.sleep(0.05)
    try:
        yield proc, lines
    finally:
        proc.terminate()
        proc.wait(15)


def send(port: int, *phases: str) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, str(SENDER), "127.0.0.1", str(port), *(f"--phase={p}" for p in phases)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    return json.loads(out.stdout)
