"""Commands from a program: one JSON object per UDP datagram.

``{"seq": N, "frame": "base"|"tool", "twist": [vx, vy, vz, wx, wy, wz]}`` (m/s, deg/s;
``frame`` defaults to base) or ``{"seq": N, "joints": [6 x deg/s]}``. A datagram whose
``seq`` is not above the last one taken is stale and ignored, unless the stream has been
silent for :data:`RESTART_S` (a sender that restarted counts from 0 again). Anything else
(not JSON, not an object, missing or extra keys, not six finite numbers) is malformed:
counted and dropped, it never moves the arm. Faster commands than the jog's full speeds
are scaled down whole (direction kept).
"""

from __future__ import annotations

import json
import math
import socket
from dataclasses import dataclass

from cellrunner.commissioning.servo import Command
from cellrunner.errors import PeerUnreachable, UsageError

#: after this long without a datagram taken, any seq starts a new stream (s)
RESTART_S = 1.0
#: datagrams read per poll at most (the rest wait for the next period)
MAX_PER_POLL = 256
MAX_DATAGRAM = 2048


class Malformed(ValueError):
    """A datagram that is not a command; the message says why."""


@dataclass(frozen=True)
class Datagram:
    seq: int
    frame: str  # base | tool | joint
    velocity: tuple[float, ...]  # m/s, rad/s


def parse_address(text: str) -> tuple[str, int]:
    """``PORT`` (on 127.0.0.1) or ``ADDR:PORT`` -> (address, port)."""
    host, _, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 < number < 65536:
        raise UsageError(f"--input udp:{text}: write udp:PORT or udp:ADDR:PORT (1-65535)")
    return host or "127.0.0.1", number


def _six(value: object, what: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 6:
        raise Malformed(f"{what} must be a list of 6 numbers")
    if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in value):
        raise Malformed(f"{what} must be a list of 6 numbers")
    out = [float(x) for x in value]
    if not all(math.isfinite(x) for x in out):
        raise Malformed(f"{what} has a value that is not finite")
    return out


def parse_datagram(data: bytes) -> Datagram:
    """One datagram -> :class:`Datagram` (velocities in SI: m/s, rad/s); Malformed."""
    try:
        obj = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise Malformed(f"not JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise Malformed("not a JSON object")
    seq = obj.get("seq")
    if not isinstance(seq, int) or isinstance(seq, bool):
        raise Malformed("seq must be an integer")
    if ("twist" in obj) == ("joints" in obj):
        raise Malformed("give one of twist or joints")
    if "joints" in obj:
        if set(obj) != {"seq", "joints"}:
            raise Malformed(f"unknown keys {sorted(set(obj) - {'seq', 'joints'})}")
        joints = _six(obj["joints"], "joints")
        return Datagram(seq, "joint", tuple(math.radians(x) for x in joints))
    if not set(obj) <= {"seq", "frame", "twist"}:
        raise Malformed(f"unknown keys {sorted(set(obj) - {'seq', 'frame', 'twist'})}")
    frame = obj.get("frame", "base")
    if frame not in ("base", "tool"):
        raise Malformed(f"frame {frame!r}: known base, tool")
    twist = _six(obj["twist"], "twist")
    return Datagram(seq, frame, (*twist[:3], *(math.radians(x) for x in twist[3:])))


class UdpInput:
    """Listens on ``host:port`` (UDP); the newest command by ``seq`` stands."""

    quit_requested = False

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.name = f"udp {host}:{port}"
        self.received = self.malformed = self.stale = 0
        self.last_error = ""
        self._sock: socket.socket | None = None
        self._seq: int | None = None
        self._last_s: float | None = None
        self._command: Command | None = None

    def open(self) -> None:
        sock = socket.socket(
            socket.AF_INET6 if ":" in self.host else socket.AF_INET, socket.SOCK_DGRAM
        )
        try:
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise PeerUnreachable(f"cannot listen on udp {self.host}:{self.port}: {exc}") from exc
        sock.setblocking(False)
        self._sock = sock

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def poll(self, now_s: float) -> Command | None:
        assert self._sock is not None, "open() first"
        for _ in range(MAX_PER_POLL):
            try:
                data = self._sock.recv(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            self.take(data, now_s)
        return self._command

    def take(self, data: bytes, now_s: float) -> None:
        """One datagram received at ``now_s``."""
        self.received += 1
        try:
            d = parse_datagram(data)
        except Malformed as exc:
            self.malformed += 1
            self.last_error = str(exc)
            return
        restarted = self._last_s is None or now_s - self._last_s > RESTART_S
        if self._seq is not None and d.seq <= self._seq and not restarted:
            self.stale += 1
            return
        self._seq, self._last_s = d.seq, now_s
        self._command = Command(d.frame, d.velocity, now_s)

    def header(self) -> str:
        return f"input: {self.name} (JSON twists or joint speeds)"

    def status(self, now_s: float) -> str:
        age = "never" if self._last_s is None else f"{now_s - self._last_s:.2f} s ago"
        text = (
            f"{self.received} datagrams, {self.malformed} malformed, {self.stale} stale; "
            f"last command {age}"
        )
        return text + (f"; last malformed: {self.last_error}" if self.malformed else "")

    def idle_reason(self, now_s: float) -> str:
        if self._last_s is None:
            return "no datagram yet"
        return f"no command for {now_s - self._last_s:.1f} s"
