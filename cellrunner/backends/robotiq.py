"""A Robotiq 2F gripper through its socket (the Robotiq URCap's server, port 63352 on the
robot controller): ASCII lines ``SET ACT 1`` / ``SET GTO 1`` / ``SET POS 255`` / ``GET OBJ``,
each answered with ``ack`` or ``OBJ n``. OBJ 2 means the jaws stopped on an object while
closing, which is what confirms a grip.

The engine addresses the gripper through the virtual channels of
:mod:`cellrunner.model.gripper` (``RQ0`` closes, ``RQ_OBJ`` reads object-detected); the
object state is polled on a thread so that ``read_state`` never waits on the socket.
"""

from __future__ import annotations

import socket
import threading
from typing import TYPE_CHECKING

from cellrunner.errors import BackendError, PeerUnreachable

if TYPE_CHECKING:
    from cellrunner.sim.world import SimWorld

PORT = 63352
POLL_S = 0.02


class RobotiqClient:
    """Construct (no I/O), ``connect()`` (activates the gripper), ``close()``."""

    def __init__(self, host: str, port: int = PORT, timeout_s: float = 2.0) -> None:
        self.host, self.port, self.timeout_s = host, port, timeout_s
        self._sock: socket.socket | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._poller: threading.Thread | None = None
        self.object_detected = False

    def connect(self) -> None:
        try:
            self._sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        except OSError as exc:
            raise PeerUnreachable(f"no Robotiq gripper at {self.host}:{self.port}: {exc}") from exc
        for command in ("SET ACT 1", "SET GTO 1", "SET SPE 255", "SET FOR 150"):
            self._ask(command)
        self._stop.clear()
        self._poller = threading.Thread(target=self._poll, name="robotiq-poll", daemon=True)
        self._poller.start()

    def move(self, closed: bool) -> None:
        """Close (position 255) or open (0); returns at once, the poller sees the outcome."""
        self._ask(f"SET POS {255 if closed else 0}")

    def close(self) -> None:
        self._stop.set()
        if self._poller is not None:
            self._poller.join(timeout=1.0)
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _poll(self) -> None:
        while not self._stop.wait(POLL_S):
            try:
                self.object_detected = self._ask("GET OBJ").strip() == "OBJ 2"
            except BackendError:
                return

    def _ask(self, line: str) -> str:
        if self._sock is None:
            raise BackendError("the Robotiq gripper is not connected")
        with self._lock:
            try:
                self._sock.sendall(line.encode() + b"\n")
                answer = self._sock.recv(64).decode(errors="replace")
            except OSError as exc:
                raise BackendError(f"Robotiq gripper at {self.host}: {exc}") from exc
        if not answer:
            raise BackendError(f"Robotiq gripper at {self.host} closed the connection")
        return answer


def serve_robotiq(
    host: str,
    world: SimWorld,
    stop: threading.Event,
    port: int = PORT,
    ready: threading.Event | None = None,
) -> None:
    """The gripper's socket for the twin: commands drive the twin's jaws (``RQ0``),
    ``GET OBJ`` reports its object sensor (``RQ_OBJ``). Runs until ``stop`` is set."""
    from cellrunner.model.gripper import ROBOTIQ_CLOSE, ROBOTIQ_OBJECT

    server = socket.create_server((host, port), reuse_port=False)
    server.settimeout(0.2)
    if ready is not None:
        ready.set()

    def handle(conn: socket.socket) -> None:
        conn.settimeout(0.2)
        buffer = b""
        with conn:
            while not stop.is_set():
                try:
                    chunk = conn.recv(256)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not chunk:
                    return
                buffer += chunk
                while b"\n" in buffer:
                    line, buffer = buffer.split(b"\n", 1)
                    words = line.decode(errors="replace").split()
                    if words[:2] == ["GET", "OBJ"]:
                        closed = bool(world.outputs.get(ROBOTIQ_CLOSE))
                        conn.sendall(
                            f"OBJ {2 if closed and world.inputs.get(ROBOTIQ_OBJECT) else 3}\n".encode()
                        )
                    elif words[:2] == ["GET", "POS"]:
                        conn.sendall(
                            f"POS {255 if world.outputs.get(ROBOTIQ_CLOSE) else 0}\n".encode()
                        )
                    elif words[:1] == ["SET"] and len(words) == 3:
                        if words[1] == "POS":
                            world.outputs[ROBOTIQ_CLOSE] = int(words[2]) > 127
                        conn.sendall(b"ack\n")
                    else:
                        conn.sendall(b"?\n")

    with server:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            threading.Thread(target=handle, args=(conn,), daemon=True).start()
