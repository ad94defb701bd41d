"""The jog's servo chain measured against `cellrunner twin` through ur_rtde: a program's
UDP twists (`cellrunner jog --input udp:PORT`, its own process) and what the arm does.

- latency: from sending the first datagram of a burst to the first changed set-point the
  controller reports (ur_rtde ``getTargetQ``) and to measured motion (``getActualQ``);
- straight line: the TCP's largest distance from the commanded line at 0.1 m/s;
- stop: how far the TCP goes, and for how long, after the last datagram;
- align: ``dry-run`` of the align example over random part offsets within its
  ``max_correction`` box: the correction's error against the true offset, looks, and the
  job's result (the twin's place verification).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import random
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CELL = ROOT / "cells" / "align_pick_ur10e.yaml"
TASK = ROOT / "tasks" / "align_pick.yaml"
CLI = (sys.executable, "-m", "cellrunner.cli.main")
ENV = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"), "PYTHONPATH": str(ROOT)}


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def process(*argv: str, ready: str, timeout_s: float = 90) -> Iterator[subprocess.Popen[str]]:
    """A cellrunner command running until the block ends, once ``ready`` is on its output."""
    proc = subprocess.Popen(
        [*CLI, *argv], cwd=ROOT, env=ENV, stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout_s
    while True:
        line = proc.stdout.readline()
        if ready in line:
            break
        if (not line and proc.poll() is not None) or time.monotonic() > deadline:
            proc.kill()
            raise SystemExit(f"{' '.join(argv[:2])} did not come up")
    try:
        yield proc
    finally:
        proc.terminate()
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()


class Sender:
    """Datagrams to the jog, with a rising seq."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.port, self.seq = port, 0

    def send(self, twist: list[float]) -> float:
        self.seq += 1
        data = json.dumps({"seq": self.seq, "frame": "base", "twist": twist}).encode()
        t = time.monotonic()
        self.sock.sendto(data, ("127.0.0.1", self.port))
        return t


def wait_still(receive: Any, timeout_s: float = 3.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and max(abs(v) for v in receive.getActualQd()) > 1e-4:
        time.sleep(0.01)
    time.sleep(0.2)


def latency(receive: Any, sender: Sender, probes: int) -> tuple[list[float], list[float]]:
    """Per probe: (first datagram -> first changed set-point, -> measured motion), s."""
    to_setpoint, to_motion = [], []
    for k in range(probes):
        wait_still(receive)
        target0, actual0 = list(receive.getTargetQ()), np.array(receive.getActualQ())
        sign = 1.0 if k % 2 == 0 else -1.0
        t0 = sender.send([sign * 0.05, 0, 0, 0, 0, 0])
        seen_set = seen_motion = None
        next_send = t0 + 0.01
        deadline = t0 + 0.3
        while time.monotonic() < deadline and (seen_set is None or seen_motion is None):
            now = time.monotonic()
            if now >= next_send:
                sender.send([sign * 0.05, 0, 0, 0, 0, 0])
                next_send += 0.01
            if seen_set is None and list(receive.getTargetQ()) != target0:
                seen_set = time.monotonic()
            if (
                seen_motion is None
                and np.max(np.abs(np.array(receive.getActualQ()) - actual0)) > 1e-6
            ):
                seen_motion = time.monotonic()
            time.sleep(0.0002)
        if seen_set is not None and seen_motion is not None:
            to_setpoint.append(seen_set - t0)
            to_motion.append(seen_motion - t0)
    return to_setpoint, to_motion


def line_and_stop(
    receive: Any, sender: Sender, speed_mps: float = 0.1, seconds: float = 1.5
) -> dict[str, float]:
    """A straight line along base +X at ``speed_mps``: largest and p99 distance of the TCP
    from the line (after the ramp), then the stop after the last datagram."""
    wait_still(receive)
    start = np.array(receive.getActualTCPPose()[:3])
    samples: list[tuple[float, np.ndarray]] = []
    t_end = time.monotonic() + seconds
    next_send = 0.0
    last = 0.0
    while time.monotonic() < t_end:
        now = time.monotonic()
        if now >= next_send:
            last = sender.send([speed_mps, 0, 0, 0, 0, 0])
            next_send = now + 0.01
        samples.append((now, np.array(receive.getActualTCPPose()[:3])))
        time.sleep(0.001)
    t_stop_deadline = time.monotonic() + 1.5
    while time.monotonic() < t_stop_deadline:
        samples.append((time.monotonic(), np.array(receive.getActualTCPPose()[:3])))
        time.sleep(0.001)
    t = np.array([s[0] for s in samples])
    p = np.array([s[1] for s in samples]) - start
    direction = np.array([1.0, 0.0, 0.0])
    along = p @ direction
    off = np.linalg.norm(p - np.outer(along, direction), axis=1)
    moving = t <= last
    at_last = along[np.searchsorted(t, last)]
    rest_i = len(t) - 1
    while rest_i > 0 and abs(along[rest_i - 1] - along[-1]) < 1e-5:
        rest_i -= 1
    return {
        "line_max_mm": float(off[moving].max() * 1000),
        "line_p99_mm": float(np.percentile(off[moving], 99) * 1000),
        "travel_mm": float(along[-1] * 1000),
        "stop_mm": float((along[-1] - at_last) * 1000),
        "stop_s": float(t[rest_i] - last),
    }


def servo_figures(host: str, probes: int) -> dict[str, Any]:
    import rtde_receive

    port = free_port()
    with process("twin", str(CELL), "--host", host, ready="virtual"):
        with process(
            "jog",
            str(CELL),
            "--robot-host",
            host,
            "--input",
            f"udp:{port}",
            ready="no datagram yet",
        ):
            receive = rtde_receive.RTDEReceiveInterface(host, 500.0)
            try:
                sender = Sender(port)
                to_setpoint, to_motion = latency(receive, sender, probes)
                line = line_and_stop(receive, sender)
            finally:
                receive.disconnect()
    return {"to_setpoint": to_setpoint, "to_motion": to_motion, **line}


def align_figures(runs: int, seed: int = 7) -> dict[str, Any]:
    """``runs`` dry-runs of the align example, each with the block at a random offset
    inside the task's max_correction box (x, y within 15 mm, yaw within 8 deg), in-process."""
    from cellrunner.cli.main import main

    rng = random.Random(seed)
    errors_mm, errors_deg, looks, codes = [], [], [], []
    failures: list[str] = []
    text = CELL.read_text()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "cells").mkdir()
        (root / "tasks").mkdir()
        for name in ("align_pick.yaml", "align_pick_blind.yaml"):
            (root / "tasks" / name).write_text((ROOT / "tasks" / name).read_text())
        for _ in range(runs):
            x, y = rng.uniform(-0.015, 0.015), rng.uniform(-0.015, 0.015)
            yaw = rng.uniform(-8, 8)
            offset = f"{{xyz: [{x:.5f}, {y:.5f}, 0], rpy: [0, 0, {yaw:.3f}]}}"
            cell = root / "cells" / "c.yaml"
            cell.write_text(text.replace("{xyz: [0.008, 0.006, 0], rpy: [0, 0, 4]}", offset))
            out = io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
                main(["dry-run", str(cell), str(root / "tasks" / "align_pick.yaml"), "--json"])
            result = json.loads(out.getvalue())
            codes.append(result["result_code"])
            if result["result_code"] != 0:
                failures.append(f"{offset}: {'; '.join(result['errors'])}")
            row = next(s for s in result["steps"] if s["kind"] == "align")
            if "corrected by" in row["message"]:
                m = row["message"]
                xyz = [float(v) for v in m.split("xyz [")[1].split("]")[0].split(",")]
                rz = float(m.split("rpy [")[1].split("]")[0].split(",")[2])
                errors_mm.append(math.hypot(xyz[0] - x * 1000, xyz[1] - y * 1000))
                errors_deg.append(abs(rz - yaw))
                looks.append(int(m.split(" in ")[1].split(" looks")[0]))
    return {
        "codes": codes,
        "errors_mm": errors_mm,
        "errors_deg": errors_deg,
        "looks": looks,
        "failures": failures,
    }
