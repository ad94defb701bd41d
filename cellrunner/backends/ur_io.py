"""Digital and analog outputs of a UR controller through RTDE input recipes.

Why not ur_rtde's ``RTDEIOInterface``: in ur_rtde 1.6.5 it never reads from its socket,
so it cannot notice a lost connection, and its destructor sends an RTDE pause that
throws on a broken socket -- ``std::terminate`` takes the whole process down (seen
against a controller that dropped the connection). This writer speaks the same RTDE
input fields (``standard_digital_output_mask``/``standard_digital_output`` ...) with
Python sockets, bounded timeouts, and errors we can translate.
"""

from __future__ import annotations

import select
import socket
import struct

from cellrunner.errors import BackendError, ConnectionLost

_RECIPES = {
    "DO": ("standard_digital_output_mask,standard_digital_output", ">BB"),
    "TO": ("tool_digital_output_mask,tool_digital_output", ">BB"),
    "CO": ("configurable_digital_output_mask,configurable_digital_output", ">BB"),
    "AO": (
        "standard_analog_output_mask,standard_analog_output_type,"
        "standard_analog_output_0,standard_analog_output_1",
        ">BBdd",
    ),
}


class IoConnectionLost(ConnectionLost):
    """The RTDE connection used for outputs dropped."""


class RtdeOutputWriter:
    """Set controller outputs over one RTDE connection; construct, ``connect``, ``close``."""

    def __init__(self, host: str, port: int = 30004, timeout_s: float = 3.0) -> None:
        self.host, self.port, self.timeout_s = host, port, timeout_s
        self._sock: socket.socket | None = None
        self._recipe_ids: dict[str, int] = {}
        self.refused: dict[str, str] = {}  # output kind -> why the controller refused it

    def connect(self) -> None:
        sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        try:
            self._exchange(sock, "V", struct.pack(">H", 2))
            for kind, (names, _) in _RECIPES.items():
                body = self._exchange(sock, "I", names.encode())
                types = body[1:].decode("ascii", "replace")
                if body[0] == 0 or "IN_USE" in types or "NOT_FOUND" in types:
                    # refused now, reported when that kind of output is used
                    self.refused[kind] = f"{names} -> {types}"
                else:
                    self._recipe_ids[kind] = body[0]
        except BaseException:
            sock.close()
            raise
        self._sock = sock

    @staticmethod
    def _exchange(sock: socket.socket, kind: str, payload: bytes) -> bytes:
        sock.sendall(struct.pack(">HB", 3 + len(payload), ord(kind)) + payload)
        while True:
            head = recv_exact(sock, 3)
            size, reply_kind = struct.unpack(">HB", head)
            body = recv_exact(sock, size - 3)
            if reply_kind == ord(kind):
                return body
            # text messages (M) may come in between; anything else is skipped as well

    def set_digital(self, kind: str, index: int, value: bool) -> None:
        """``kind`` DO (standard), CO (configurable) or TO (tool); bit ``index``."""
        mask = 1 << index
        self._send(kind, struct.pack(_RECIPES[kind][1], mask, mask if value else 0))

    def set_analog_voltage(self, index: int, fraction: float) -> None:
        """Analog output ``index`` in voltage mode at ``fraction`` of its 0-10 V range."""
        values = [0.0, 0.0]
        values[index] = fraction
        self._send("AO", struct.pack(_RECIPES["AO"][1], 1 << index, 1 << index, *values))

    def _send(self, kind: str, fields: bytes) -> None:
        if self._sock is None:
            raise IoConnectionLost(f"outputs of {self.host}: not connected")
        if kind not in self._recipe_ids:
            raise BackendError(
                f"the controller at {self.host} refused the RTDE inputs for {kind} outputs "
                f"({self.refused.get(kind, 'not set up')}); another RTDE client or a fieldbus "
                "(EtherNet/IP, PROFINET, Modbus) may own them"
            )
        payload = bytes([self._recipe_ids[kind]]) + fields
        if not self._alive():
            self.close()
            raise IoConnectionLost(
                f"the controller at {self.host} closed the RTDE connection for outputs"
            )
        try:
            self._sock.sendall(struct.pack(">HB", 3 + len(payload), ord("U")) + payload)
        except OSError as exc:
            self.close()
            raise IoConnectionLost(
                f"lost the RTDE connection for outputs to {self.host}: {exc}"
            ) from exc

    def _alive(self) -> bool:
        """False once the controller closed the connection (a write would vanish)."""
        assert self._sock is not None
        readable, _, _ = select.select([self._sock], [], [], 0)
        if not readable:
            return True
        try:
            self._sock.setblocking(False)
            data = self._sock.recv(4096, socket.MSG_PEEK)
        except BlockingIOError:
            return True
        except OSError:
            return False
        finally:
            self._sock.settimeout(self.timeout_s)
        if data:  # an unsolicited message (text); drop it
            self._sock.recv(len(data))
            return True
        return False

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def recv_exact(sock: socket.socket, n: int) -> bytes:
    """Exactly ``n`` bytes from ``sock`` (TCP delivers RTDE frames in pieces)."""
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("controller closed the connection")
        data += chunk
    return data


#: the outputs :func:`write_output` knows
CHANNELS = "DO0-7, CO0-7, TO0-1, AO0-1"


def _channel(name: str) -> tuple[str, int]:
    kind, index = name[:2].upper(), name[2:]
    limits = {"DO": 8, "CO": 8, "TO": 2, "AO": 2, "DI": 8, "CI": 8, "TI": 2, "AI": 2}
    if kind not in limits or not index.isdigit() or int(index) >= limits[kind]:
        raise BackendError(f"unknown output channel {name!r}; valid: {CHANNELS}")
    return kind, int(index)


def write_output(io: RtdeOutputWriter | None, channel: str, value: bool | float) -> None:
    """Set output ``channel`` (DOn, COn, TOn: a bool; AOn: a fraction of its range)."""
    kind, index = _channel(channel)
    if io is None:
        raise BackendError("not connected; call connect() first")
    try:
        if kind in ("DO", "CO", "TO"):
            io.set_digital(kind, index, bool(value))
        elif kind == "AO":
            if not 0.0 <= float(value) <= 1.0:
                raise BackendError(f"{channel}: {value} is not a fraction of the range in [0, 1]")
            io.set_analog_voltage(index, float(value))
        else:
            raise BackendError(f"{channel} is an input; valid outputs: {CHANNELS}")
    except IoConnectionLost as exc:
        raise ConnectionLost(str(exc)) from exc
