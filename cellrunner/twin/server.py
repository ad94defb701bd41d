"""Network face of the virtual controller, its real-time loop, and the fault channel.

:class:`TwinServer` binds, on one host address:

- Dashboard server, TCP 29999 (``twin.dashboard``);
- RTDE, TCP 30004 (``twin.rtde``), any number of clients;
- script receivers, TCP 30001, 30002, 30003 (``twin.script``): programs sent there are
  run (ur_rtde's control script, or a simple program). The twin does not stream the
  primary/secondary/real-time state packages on these ports;
- the **fault channel**, TCP 29990 (not a UR port): one command per line, one reply
  line, ``ok ...`` or ``error ...``; see :data:`FAULT_COMMANDS`.

Two threads: an I/O thread (one selector over every socket) and the real-time loop,
which ticks the controller every period (2 ms / 8 ms), then sends each started RTDE
client the data packages due. Sockets are non-blocking; a client that stops reading
loses data packages (never replies) once 64 KiB are queued for it.
"""

from __future__ import annotations

import errno
import json
import re
import selectors
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cellrunner.errors import InternalError
from cellrunner.model.robots import RobotSpec, robot_spec
from cellrunner.thread_priority import realtime as realtime_priority
from cellrunner.twin import dashboard
from cellrunner.twin.controller import (
    Controller,
    ControllerConfig,
)
from cellrunner.twin.fault_channel import (
    FAULT_COMMANDS,
    FAULT_PORT,
    FaultClient,
    controller_command,
    controller_state,
    loop_timing,
    parse_channel,
)
from cellrunner.twin.physics import KinematicPhysics, Physics
from cellrunner.twin.rtde import InputOwners, RtdeError, RtdeSession
from cellrunner.twin.script import parse_program
from cellrunner.twin.script_text import ScriptError
from cellrunner.twin.simple_program import SimpleProgram

_SEND_LIMIT = 64 * 1024
#: SCHED_FIFO priorities of the twin's threads (their own: see cellrunner.thread_priority)
CONTROLLER_PRIORITY = 20  # the real-time loop, as a real controller's
IO_PRIORITY = 10  # commands must not wait behind other processes either

__all__ = ["FaultClient", "TwinPorts", "TwinServer", "make_controller", "parse_channel", "run_twin"]


@dataclass(frozen=True)
class TwinPorts:
    dashboard: int = 29999
    rtde: int = 30004
    script: tuple[int, ...] = (30001, 30002, 30003)
    fault: int = FAULT_PORT


class _Conn:
    """One accepted socket: its role, buffers and (for RTDE) its protocol session."""

    def __init__(self, sock: socket.socket, role: str) -> None:
        self.sock = sock
        self.role = role
        self.inbuf = bytearray()
        self.outbuf = bytearray()
        self.lock = threading.Lock()
        self.session: RtdeSession | None = None
        self.closed = False

    def send(self, data: bytes, droppable: bool = False) -> None:
        with self.lock:
            if self.closed:
                return
            if self.outbuf:
                if droppable and len(self.outbuf) > _SEND_LIMIT:
                    return
                self.outbuf += data
                return
            try:
                n = self.sock.send(data)
            except BlockingIOError:
                n = 0
            except OSError:
                self.closed = True
                return
            if n < len(data):
                self.outbuf += data[n:]

    def flush(self) -> None:
        with self.lock:
            if self.closed or not self.outbuf:
                return
            try:
                n = self.sock.send(self.outbuf)
                del self.outbuf[:n]
            except BlockingIOError:
                pass
            except OSError:
                self.closed = True


class TwinServer:
    """Serve one :class:`Controller` on ``host``; construct, ``start()``, ``stop()``."""

    def __init__(
        self,
        controller: Controller,
        host: str = "127.0.0.2",
        ports: TwinPorts | None = None,
        realtime: bool = True,
    ) -> None:
        self.ctl = controller
        self.realtime = realtime  # try SCHED_FIFO for the loop thread (ignored if not permitted)
        self.host = host
        self.ports = ports or TwinPorts()
        self.owners = InputOwners()
        self._selector: selectors.BaseSelector | None = None
        self._listeners: list[socket.socket] = []
        self._conns: dict[int, _Conn] = {}
        self._conns_lock = threading.Lock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._blackout_until = 0.0
        self._next_session = 1
        self.loop_periods_s: list[float] = []  # recent loop periods, for diagnostics

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        self._selector = selectors.DefaultSelector()
        roles = [
            (self.ports.dashboard, "dashboard"),
            (self.ports.rtde, "rtde"),
            (self.ports.fault, "fault"),
        ]
        roles += [(p, "script") for p in self.ports.script]
        try:
            for port, role in roles:
                listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                listener.bind((self.host, port))
                listener.listen(16)
                listener.setblocking(False)
                self._listeners.append(listener)
                self._selector.register(listener, selectors.EVENT_READ, ("listen", role))
        except OSError:
            self._close_listeners()
            raise
        for target, name in ((self._io_loop, "twin-io"), (self._rt_loop, "twin-rt")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._drop_clients()
        self._close_listeners()
        if self._selector is not None:
            self._selector.close()

    def _close_listeners(self) -> None:
        for listener in self._listeners:
            listener.close()
        self._listeners.clear()

    # ------------------------------------------------------------------ real-time loop

    def _rt_loop(self) -> None:
        period = self.ctl.period_s
        realtime = self.realtime and realtime_priority(CONTROLLER_PRIORITY) is not None
        spin_s = 0.00005 if realtime else 0.0002  # sleep until this close, then spin
        self.ctl.add_log(
            f"real-time loop at {1 / period:g} Hz, SCHED_FIFO {'on' if realtime else 'off'}"
        )
        deadline = time.perf_counter() + period
        last = time.perf_counter()
        while not self._stop.is_set():
            now = time.perf_counter()
            remaining = deadline - now
            time.sleep(max(remaining - spin_s, 0.0001))  # always yield a little
            while time.perf_counter() < deadline:
                pass
            now = time.perf_counter()
            self.loop_periods_s.append(now - last)
            if len(self.loop_periods_s) > 5000:
                del self.loop_periods_s[:1000]
            last = now
            deadline += period
            if now - deadline > 5 * period:  # fell far behind (suspended): resynchronise
                deadline = now + period
            with self._conns_lock:
                conns = list(self._conns.values())
            outgoing: list[tuple[_Conn, list[bytes]]] = []
            with self.ctl.lock:
                self.ctl.tick()
                for conn in conns:
                    if conn.session is not None and conn.session.started:
                        outgoing.append((conn, conn.session.output_packets()))
            for conn in conns:
                conn.flush()
            for conn, packets in outgoing:
                for packet in packets:
                    conn.send(packet, droppable=True)

    # ------------------------------------------------------------------ I/O loop

    def _io_loop(self) -> None:
        assert self._selector is not None
        if self.realtime:  # commands must not wait behind other processes either
            realtime_priority(IO_PRIORITY)
        while not self._stop.is_set():
            try:
                events = self._selector.select(timeout=0.05)
            except OSError:
                continue
            for key, _ in events:
                data = key.data
                if isinstance(data, tuple):
                    # a tuple key: one of our listening sockets (registered as such)
                    self._accept(key.fileobj, data[1])  # type: ignore[arg-type]
                else:
                    self._read(data)

    def _accept(self, listener: socket.socket, role: str) -> None:
        try:
            sock, _ = listener.accept()
        except OSError:
            return
        if time.monotonic() < self._blackout_until:
            sock.close()
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn = _Conn(sock, role)
        if role == "rtde":
            conn.session = RtdeSession(self._next_session, self.ctl, self.owners)
            self._next_session += 1
        with self._conns_lock:
            self._conns[sock.fileno()] = conn
        assert self._selector is not None
        self._selector.register(sock, selectors.EVENT_READ, conn)
        if role == "dashboard":
            conn.send((dashboard.GREETING + "\n").encode())

    def _read(self, conn: _Conn) -> None:
        try:
            data = conn.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno not in (errno.ECONNRESET, errno.EPIPE):
                self.ctl.add_log(f"socket error: {exc}")
            data = b""
        if not data:
            self._close(conn)
            return
        try:
            handler: Callable[[_Conn, bytes], bool] = getattr(self, f"_on_{conn.role}")
            keep = handler(conn, data)
        except (RtdeError, UnicodeDecodeError) as exc:
            self.ctl.add_log(f"{conn.role} protocol error: {exc}")
            keep = False
        if not keep or conn.closed:
            self._close(conn)

    def _close(self, conn: _Conn) -> None:
        with self._conns_lock:
            self._conns.pop(conn.sock.fileno(), None)
        with conn.lock:
            conn.closed = True
        if conn.session is not None:
            conn.session.close()
        try:
            assert self._selector is not None
            self._selector.unregister(conn.sock)
        except (KeyError, ValueError, OSError):
            pass
        conn.sock.close()

    def _drop_clients(self, keep_fault: bool = False) -> None:
        with self._conns_lock:
            conns = [c for c in self._conns.values() if not (keep_fault and c.role == "fault")]
        for conn in conns:
            self._close(conn)

    # ------------------------------------------------------------------ protocols

    def _on_rtde(self, conn: _Conn, data: bytes) -> bool:
        assert conn.session is not None
        for reply in conn.session.feed(data):
            conn.send(reply)
        return True

    def _lines(self, conn: _Conn, data: bytes) -> list[str]:
        conn.inbuf += data
        *lines, rest = conn.inbuf.split(b"\n")
        conn.inbuf = bytearray(rest)
        return [line.decode("utf-8", "replace").rstrip("\r") for line in lines]

    def _on_dashboard(self, conn: _Conn, data: bytes) -> bool:
        for line in self._lines(conn, data):
            with self.ctl.lock:
                reply, close = dashboard.handle(self.ctl, line)
            conn.send((reply + "\n").encode())
            if close:
                return False
        return True

    def _on_script(self, conn: _Conn, data: bytes) -> bool:
        conn.inbuf += data
        text = conn.inbuf.decode("utf-8", "replace")
        consumed = 0
        while True:
            rest = text[consumed:]
            stripped = rest.lstrip()
            if not stripped:
                consumed = len(text)
                break
            lead = len(rest) - len(stripped)
            if re.match(r"(def|sec)\s+\w+\s*\(", stripped):
                end = re.search(r"^end[ \t\r]*(\n|$)", stripped, re.MULTILINE)
                if end is None or (end.group(1) == "" and not stripped.endswith("end")):
                    break
                program_text = stripped[: end.end()]
            else:
                newline = stripped.find("\n")
                if newline < 0:
                    break
                program_text = stripped[: newline + 1]
            consumed += lead + len(program_text)
            self._run_program(program_text)
        conn.inbuf = bytearray(text[consumed:].encode())
        return True

    def _run_program(self, text: str) -> None:
        with self.ctl.lock:
            if not self.ctl.remote_control:
                self.ctl.add_log("program ignored: robot in local control")
                return
            try:
                _kind, program = parse_program(text)
            except ScriptError as exc:
                self.ctl.add_log(f"program refused: {exc}")
                return
            if isinstance(program, SimpleProgram) and program.secondary:
                program.run_all_now(self.ctl)
                return
            self.ctl.start_program(program)

    # ------------------------------------------------------------------ fault channel

    def _on_fault(self, conn: _Conn, data: bytes) -> bool:
        for line in self._lines(conn, data):
            if not line.strip():
                continue
            try:
                reply = "ok " + self.fault(line)
            except (ValueError, IndexError) as exc:
                reply = f"error {exc}"
            conn.send((reply.rstrip() + "\n").encode())
        return True

    def fault(self, line: str) -> str:
        """Execute one fault-channel command (see :data:`FAULT_COMMANDS`); the reply text."""
        words = line.split()
        cmd, args = words[0].lower(), words[1:]
        ctl = self.ctl
        if cmd == "ping":
            return "pong"
        if cmd in ("disconnect", "blackout"):
            if cmd == "blackout":
                self._blackout_until = time.monotonic() + float(args[0])
            self._drop_clients(keep_fault=True)
            return cmd
        if cmd == "timing":
            return json.dumps(self.timing())
        with ctl.lock:
            if cmd == "state":
                return json.dumps(self.state())
            reply = controller_command(ctl, cmd, args)
        if reply is None:  # ValueError: the fault channel answers it as "error TEXT" (_on_fault)
            raise ValueError(
                f"unknown command {cmd!r}; known: "
                + ", ".join(ln.split()[0] for ln in FAULT_COMMANDS.splitlines())
            )
        return reply

    def timing(self) -> dict[str, float]:
        """Statistics of the real-time loop's period (s) and its deviation from nominal."""
        return loop_timing(self.loop_periods_s[-4000:], self.ctl.period_s)

    def state(self) -> dict[str, Any]:
        """A JSON-able snapshot of the controller (call under the lock)."""
        clients = sum(1 for c in self._conns.values() if c.role != "fault")
        return controller_state(self.ctl) | {"clients": clients}


# ---------------------------------------------------------------------- entry point


def make_controller(
    robot: str | RobotSpec,
    physics: Physics | None = None,
    loopback: dict[str, str] | None = None,
    **config: Any,
) -> Controller:
    """A controller for model ``robot`` (``"ur5e"`` or a RobotSpec); ``config`` sets
    :class:`ControllerConfig` fields (timings, initial joints, versions...).

    Without ``physics`` the arm is a :class:`KinematicPhysics`; ``loopback`` wires its
    outputs to inputs by channel name (``{"DO0": "DI0"}``: a valve and its sensor)."""
    spec = robot_spec(robot) if isinstance(robot, str) else robot
    if physics is None:
        wiring = {parse_channel(out): parse_channel(inp) for out, inp in (loopback or {}).items()}
        physics = KinematicPhysics(spec, loopback=wiring)
    elif loopback:
        raise InternalError(
            "loopback wires the kinematic physics only; this physics has its own IO"
        )
    return Controller(ControllerConfig(spec=spec, **config), physics)


def run_twin(
    robot: str | RobotSpec,
    host: str = "127.0.0.2",
    physics: Physics | None = None,
    stop_event: Any = None,
    ports: TwinPorts | None = None,
    ready: Any = None,
    loopback: dict[str, str] | None = None,
    **config: Any,
) -> None:
    """Serve a virtual UR controller on ``host`` until ``stop_event`` is set.

    ``physics`` defaults to :class:`~cellrunner.twin.physics.KinematicPhysics` (with
    ``loopback`` wiring, see :func:`make_controller`); ``config`` sets
    :class:`ControllerConfig` fields, e.g. ``q_initial_rad`` (the cell's home) or
    ``unlock_delay_s``; ``ready`` (an Event) is set once every port is bound. Without ``stop_event`` it
    serves until interrupted (Ctrl-C / SIGTERM in the caller).
    """
    server = TwinServer(make_controller(robot, physics, loopback, **config), host, ports)
    server.start()
    try:
        if ready is not None:
            ready.set()
        if stop_event is None:
            stop_event = threading.Event()
        while not stop_event.wait(0.2):  # a threading or multiprocessing Event
            pass
    finally:
        server.stop()
