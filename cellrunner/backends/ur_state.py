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

import numpy as np

from cellrunner.backends.ur_io import recv_exact
from cellrunner.model.gripper import ROBOTIQ_OBJECT
from cellrunner.model.robot_state import RobotState, Safety

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

    def value(self, name: str) -> Any:
        """The latest package's value of subscribed variable ``name``."""
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


#: the variables the UR backend subscribes
RECEIVE_VARIABLES = [
    "timestamp",
    "actual_q",
    "actual_qd",
    "target_q",
    "actual_TCP_force",
    "robot_mode",
    "safety_mode",
    "robot_status_bits",
    "safety_status_bits",
    "runtime_state",
    "actual_digital_input_bits",
    "actual_digital_output_bits",
    "standard_analog_input0",
    "standard_analog_input1",
    "standard_analog_output0",
    "standard_analog_output1",
]
ROBOT_MODE_RUNNING = 7
ROBOT_MODE_IDLE = 5


def safety_of(bits: int) -> Safety:
    if bits & (1 << 5 | 1 << 6 | 1 << 7):
        return Safety.EMERGENCY_STOP
    if bits & (1 << 8 | 1 << 9):
        return Safety.FAULT
    if bits & (1 << 2 | 1 << 4):
        return Safety.PROTECTIVE_STOP
    return Safety.NORMAL


def robot_state_of(receive: Any, *, control_lost: bool, robotiq_object: bool | None) -> RobotState:
    """The arm's state from the latest package of ``receive`` (DISCONNECTED when the
    stream or, ``control_lost``, the control process is down); ``robotiq_object``, when a
    Robotiq gripper is fitted, is its object-detected input."""
    if receive is None or not receive.isConnected():
        return RobotState(
            0.0, np.zeros(6), np.zeros(6), np.zeros(6), Safety.DISCONNECTED, powered=False
        )
    safety = Safety.DISCONNECTED if control_lost else safety_of(receive.getSafetyStatusBits())
    inputs_bits, output_bits = (
        receive.getActualDigitalInputBits(),
        receive.getActualDigitalOutputBits(),
    )
    inputs: dict[str, float | bool] = {}
    outputs: dict[str, float | bool] = {}
    for prefix, bits, target in (("I", inputs_bits, inputs), ("O", output_bits, outputs)):
        for i in range(8):
            target[f"D{prefix}{i}"] = bool(bits >> i & 1)
            target[f"C{prefix}{i}"] = bool(bits >> (8 + i) & 1)
        for i in range(2):
            target[f"T{prefix}{i}"] = bool(bits >> (16 + i) & 1)
    inputs["AI0"], inputs["AI1"] = (
        receive.getStandardAnalogInput0(),
        receive.getStandardAnalogInput1(),
    )
    if robotiq_object is not None:
        inputs[ROBOTIQ_OBJECT] = robotiq_object
    outputs["AO0"], outputs["AO1"] = (
        receive.getStandardAnalogOutput0(),
        receive.getStandardAnalogOutput1(),
    )
    return RobotState(
        time_s=receive.getTimestamp(),
        q_rad=np.array(receive.getActualQ()),
        qd_rad_s=np.array(receive.getActualQd()),
        wrench_N=np.array(receive.getActualTCPForce()),
        safety=safety,
        inputs=inputs,
        outputs=outputs,
        powered=bool(receive.getRobotStatus() & 1),
        brakes_released=receive.getRobotMode() == ROBOT_MODE_RUNNING,
    )
