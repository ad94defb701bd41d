"""The controller's state stream (RTDE outputs) read with Python sockets.

Why not ur_rtde's ``RTDEReceiveInterface``: its ``disconnect()`` (and so its destructor)
on a link the controller dropped waits about 0.5 s inside the library while holding
Python's GIL, which froze every thread of ``serve`` (the PLC heartbeat among them) on
each reconnect. This reader subscribes the same variables, keeps the latest package from
a daemon thread that blocks in ``recv`` without the GIL, and offers the getters the UR
backend uses. ``isConnected()`` turns False the moment the controller closes the stream.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from typing import Any

from cellrunner.backends.ur_io import recv_exact

#: RTDE type name -> struct code (big-endian, SPEC of the RTDE guide)
_TYPES = {
    "DOUBLE": "d",
    "UINT64": "Q",
    "UINT32": "I",
    "INT32": "i",
    "UINT8": "B",
    "BOOL": "?",
    "VECTOR6D": "6d",
    "VECTOR3D": "3d",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
}
_WIDTH = {"VECTOR6D": 6, "VECTOR3D": 3, "VECTOR6INT32": 6, "VECTOR6UINT32": 6}


class RtdeStateReader:
    """Subscribe ``variables`` at ``rate_hz``; construct, :meth:`connect`, getters,
    :meth:`disconnect`. Getters return the latest package's values."""

    def __init__(
        self,
        host: str,
        rate_hz: float,
        variables: list[str],
        *,
        port: int = 30004,
        timeout_s: float = 3.0,
    ) -> None:
        self.host, self.rate_hz, self.variables, self.port, self.timeout_s = (
            host,
            rate_hz,
            variables,
            port,
            timeout_s,
        )
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._latest: dict[str, Any] = {}
        self._connected = False
        self._first = threading.Event()

    def connect(self) -> None:
        """Negotiate protocol 2, set up the output recipe, start, and wait for the first
        package (bounded by ``timeout_s``); raises OSError/ConnectionError on failure."""
        from cellrunner.backends.ur_io import RtdeOutputWriter

        sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        try:
            exchange = RtdeOutputWriter._exchange
            if not exchange(sock, "V", struct.pack(">H", 2))[0]:
                raise ConnectionError(
                    f"the controller at {self.host} refused RTDE protocol version 2"
                )
            body = exchange(
                sock, "O", struct.pack(">d", self.rate_hz) + ",".join(self.variables).encode()
            )
            types = body[1:].decode("ascii", "replace").split(",")
            unknown = [
                f"{n} ({t})" for n, t in zip(self.variables, types, strict=False) if t not in _TYPES
            ]
            if unknown or len(types) != len(self.variables):
                raise ConnectionError(
                    f"the controller at {self.host} cannot stream {', '.join(unknown) or types}"
                )
            if not exchange(sock, "S", b"")[0]:
                raise ConnectionError(
                    f"the controller at {self.host} refused to start the RTDE stream"
                )
        except BaseException:
            sock.close()
            raise
        fmt = ">B" + "".join(_TYPES[t] for t in types)
        self._sock, self._connected = sock, True
        self._thread = threading.Thread(
            target=self._receive,
            args=(sock, struct.Struct(fmt), types),
            daemon=True,
            name="rtde-state",
        )
        self._thread.start()
        if not self._first.wait(self.timeout_s):
            self.disconnect()
            raise ConnectionError(f"no RTDE state from {self.host} within {self.timeout_s:g} s")

    def _receive(self, sock: socket.socket, layout: struct.Struct, types: list[str]) -> None:
        sock.settimeout(None)
        try:
            while True:
                size, kind = struct.unpack(">HB", recv_exact(sock, 3))
                body = recv_exact(sock, size - 3)
                if kind != ord("U") or len(body) != layout.size:
                    continue  # text messages and the like
                flat = layout.unpack(body)[1:]
                latest, i = {}, 0
                for name, type_name in zip(self.variables, types, strict=True):
                    width = _WIDTH.get(type_name, 1)
                    latest[name] = list(flat[i : i + width]) if width > 1 else flat[i]
                    i += width
                self._latest = latest
                self._first.set()
        except (OSError, ConnectionError, struct.error):
            pass
        finally:
            self._connected = False

    def isConnected(self) -> bool:  # ur_rtde's name, so the backend reads either
        return self._connected

    def disconnect(self) -> None:
        """Close the stream; returns at once (the reader thread ends on the closed socket)."""
        sock, self._sock = self._sock, None
        self._connected = False
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()

    def _get(self, name: str) -> Any:
        return self._latest[name]

    def getTimestamp(self) -> float:
        return float(self._get("timestamp"))

    def getActualQ(self) -> list[float]:
        return list(self._get("actual_q"))

    def getActualQd(self) -> list[float]:
        return list(self._get("actual_qd"))

    def getTargetQ(self) -> list[float]:
        return list(self._get("target_q"))

    def getActualTCPForce(self) -> list[float]:
        return list(self._get("actual_TCP_force"))

    def getRobotMode(self) -> int:
        return int(self._get("robot_mode"))

    def getSafetyMode(self) -> int:
        return int(self._get("safety_mode"))

    def getRobotStatus(self) -> int:
        return int(self._get("robot_status_bits"))

    def getSafetyStatusBits(self) -> int:
        return int(self._get("safety_status_bits"))

    def getRuntimeState(self) -> int:
        return int(self._get("runtime_state"))

    def getActualDigitalInputBits(self) -> int:
        return int(self._get("actual_digital_input_bits"))

    def getActualDigitalOutputBits(self) -> int:
        return int(self._get("actual_digital_output_bits"))

    def getStandardAnalogInput0(self) -> float:
        return float(self._get("standard_analog_input0"))

    def getStandardAnalogInput1(self) -> float:
        return float(self._get("standard_analog_input1"))

    def getStandardAnalogOutput0(self) -> float:
        return float(self._get("standard_analog_output0"))

    def getStandardAnalogOutput1(self) -> float:
        return float(self._get("standard_analog_output1"))
