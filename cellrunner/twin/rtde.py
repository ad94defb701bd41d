"""RTDE (port 30004) of the virtual controller: framing, recipes, the variable table.

Wire format (UR's RTDE guide, protocol version 2): every message is
``uint16 size (header included) | uint8 type | payload``, big-endian. Types: ``V``
request protocol version, ``v`` get URControl version, ``M`` text message, ``O``
setup outputs (``double frequency`` + comma-separated names), ``I`` setup inputs,
``S`` start, ``P`` pause, ``U`` data package (``uint8 recipe id`` + fields).
Setup replies carry the new recipe id and the comma-separated field types; a name the
controller does not know is typed ``NOT_FOUND`` (recipe id 0) and an input another
client already writes is ``IN_USE``.

:class:`RtdeSession` is the protocol of one connection without the socket: ``feed``
takes whatever bytes arrived (any split or coalescing) and returns the replies;
``output_packets`` returns the data packages due this controller period.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.twin.controller import Controller
from cellrunner.twin.rtde_io import (
    apply_input_package,
    joint_mode,
    robot_status_bits,
    safety_status_bits,
)

HEADER = struct.Struct(">HB")
V, v, M, O, I, S, P, U = (ord(c) for c in "VvMOISPU")  # noqa: E741

_FORMATS = {
    "DOUBLE": "d",
    "UINT64": "Q",
    "UINT32": "I",
    "INT32": "i",
    "VECTOR6D": "6d",
    "VECTOR3D": "3d",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
    "BOOL": "?",
    "UINT8": "B",
}
_VECTOR = {"VECTOR6D", "VECTOR3D", "VECTOR6INT32", "VECTOR6UINT32"}


@dataclass(frozen=True)
class OutputVar:
    type: str
    get: Callable[[Controller], Any]
    min_e: tuple[int, int] = (5, 0)  # (major, minor) on e-Series; None: absent
    min_cb3: tuple[int, int] | None = (3, 0)  # on CB3; None: absent


def _register(name: str, i: int) -> Callable[[Controller], Any]:
    """The getter of element ``i`` of the controller's register list ``name``."""
    return lambda c: getattr(c.reg, name)[i]


def _bit_register(name: str, i: int) -> Callable[[Controller], bool]:
    """The getter of bit ``i`` of the controller's bit register ``name``."""
    return lambda c: bool(getattr(c.reg, name) >> i & 1)


def _zeros6(ctl: Controller) -> list[float]:
    return [0.0] * 6


def _motion_outputs() -> dict[str, OutputVar]:
    """The joint and TCP state: joint values in rad, rad/s, rad/s²; TCP poses in the base frame
    (m, axis-angle rad), speeds in m/s and rad/s, the TCP wrench in N and N·m."""
    return {
        "timestamp": OutputVar("DOUBLE", lambda c: c.time_s),
        "target_q": OutputVar("VECTOR6D", lambda c: c.target_q),
        "target_qd": OutputVar("VECTOR6D", lambda c: c.target_qd),
        "target_qdd": OutputVar("VECTOR6D", lambda c: c.target_qdd),
        "target_current": OutputVar("VECTOR6D", _zeros6),
        "target_moment": OutputVar("VECTOR6D", _zeros6),
        "actual_q": OutputVar("VECTOR6D", lambda c: c.meas.q_rad),
        "actual_qd": OutputVar("VECTOR6D", lambda c: c.meas.qd_rad_s),
        "actual_current": OutputVar("VECTOR6D", _zeros6),
        "actual_current_window": OutputVar("VECTOR6D", _zeros6),
        "actual_current_as_torque": OutputVar("VECTOR6D", _zeros6, (5, 23), None),
        "joint_control_output": OutputVar("VECTOR6D", _zeros6),
        "actual_TCP_pose": OutputVar("VECTOR6D", lambda c: c.actual_tcp_pose),
        "actual_TCP_speed": OutputVar("VECTOR6D", lambda c: c.actual_tcp_speed),
        "actual_TCP_force": OutputVar("VECTOR6D", lambda c: c.wrench),
        "target_TCP_pose": OutputVar("VECTOR6D", lambda c: c.target_tcp_pose),
        "target_TCP_speed": OutputVar("VECTOR6D", lambda c: c.target_tcp_speed),
    }


def _status_outputs() -> dict[str, OutputVar]:
    """The controller's status: modes, digital bits, voltages (V), currents (A), temperatures (°C)."""
    return {
        "actual_digital_input_bits": OutputVar("UINT64", lambda c: c.digital_input_bits),
        "joint_temperatures": OutputVar("VECTOR6D", lambda c: [30.0] * 6),
        "actual_execution_time": OutputVar("DOUBLE", lambda c: 0.2),
        "robot_mode": OutputVar("INT32", lambda c: int(c.robot_mode)),
        "joint_mode": OutputVar("VECTOR6INT32", lambda c: [joint_mode(c)] * 6),
        "safety_mode": OutputVar("INT32", lambda c: int(c.safety_mode)),
        "safety_status": OutputVar("INT32", lambda c: int(c.safety_mode), (5, 4), (3, 10)),
        "actual_tool_accelerometer": OutputVar("VECTOR3D", lambda c: [0.0, 0.0, 9.81]),
        "speed_scaling": OutputVar("DOUBLE", lambda c: 1.0 if c.can_move else 0.0),
        "target_speed_fraction": OutputVar("DOUBLE", lambda c: c.speed_slider),
        "actual_momentum": OutputVar("DOUBLE", lambda c: 0.0),
        "actual_main_voltage": OutputVar("DOUBLE", lambda c: 48.0),
        "actual_robot_voltage": OutputVar(
            "DOUBLE", lambda c: 48.0 if robot_status_bits(c) & 1 else 0.0
        ),
        "actual_robot_current": OutputVar(
            "DOUBLE", lambda c: 0.5 if robot_status_bits(c) & 1 else 0.0
        ),
        "actual_joint_voltage": OutputVar("VECTOR6D", lambda c: [48.0] * 6),
        "actual_digital_output_bits": OutputVar("UINT64", lambda c: c.digital_output_bits),
        "runtime_state": OutputVar("UINT32", lambda c: int(c.runtime_state)),
        "elbow_position": OutputVar("VECTOR3D", lambda c: [0.0] * 3),
        "elbow_velocity": OutputVar("VECTOR3D", lambda c: [0.0] * 3),
        "robot_status_bits": OutputVar("UINT32", lambda c: robot_status_bits(c)),
        "safety_status_bits": OutputVar("UINT32", lambda c: safety_status_bits(c)),
        "analog_io_types": OutputVar("UINT32", lambda c: c.analog_out_types << 2),
    }


def _io_outputs() -> dict[str, OutputVar]:
    """The analog I/O (V or A), the Euromap67 and the tool connector's I/O."""
    return {
        "standard_analog_input0": OutputVar("DOUBLE", lambda c: c.meas.analog_inputs[0]),
        "standard_analog_input1": OutputVar("DOUBLE", lambda c: c.meas.analog_inputs[1]),
        "standard_analog_output0": OutputVar("DOUBLE", lambda c: c.analog_out[0]),
        "standard_analog_output1": OutputVar("DOUBLE", lambda c: c.analog_out[1]),
        "io_current": OutputVar("DOUBLE", lambda c: 0.1),
        "euromap67_input_bits": OutputVar("UINT32", lambda c: 0),
        "euromap67_output_bits": OutputVar("UINT32", lambda c: 0),
        "euromap67_24V_voltage": OutputVar("DOUBLE", lambda c: 0.0),
        "euromap67_24V_current": OutputVar("DOUBLE", lambda c: 0.0),
        "tool_mode": OutputVar("UINT32", lambda c: 253 if c.robot_mode == 7 else 255),
        "tool_analog_input_types": OutputVar("UINT32", lambda c: 0),
        "tool_analog_input0": OutputVar("DOUBLE", lambda c: 0.0),
        "tool_analog_input1": OutputVar("DOUBLE", lambda c: 0.0),
        "tool_output_voltage": OutputVar("INT32", lambda c: 24),
        "tool_output_current": OutputVar("DOUBLE", lambda c: 0.0),
        "tool_temperature": OutputVar("DOUBLE", lambda c: 30.0),
    }


def _misc_outputs() -> dict[str, OutputVar]:
    """The TCP force scalar (N), the bit-register words, the tool output modes, the payload
    (kg, centre of gravity in m in the flange frame) and the newer diagnostics."""
    return {
        "tcp_force_scalar": OutputVar("DOUBLE", lambda c: float(np.linalg.norm(c.wrench[:3]))),
        "output_bit_registers0_to_31": OutputVar(
            "UINT32", lambda c: c.reg.output_bits & 0xFFFFFFFF
        ),
        "output_bit_registers32_to_63": OutputVar(
            "UINT32", lambda c: c.reg.output_bits >> 32 & 0xFFFFFFFF
        ),
        "input_bit_registers0_to_31": OutputVar("UINT32", lambda c: c.reg.input_bits & 0xFFFFFFFF),
        "input_bit_registers32_to_63": OutputVar(
            "UINT32", lambda c: c.reg.input_bits >> 32 & 0xFFFFFFFF
        ),
        "tool_output_mode": OutputVar("UINT8", lambda c: 0, (5, 3), None),
        "tool_digital_output0_mode": OutputVar("UINT8", lambda c: 1, (5, 3), None),
        "tool_digital_output1_mode": OutputVar("UINT8", lambda c: 1, (5, 3), None),
        "payload": OutputVar("DOUBLE", lambda c: c.payload_kg, (5, 5), (3, 11)),
        "payload_cog": OutputVar("VECTOR3D", lambda c: c.payload_cog_m, (5, 5), (3, 11)),
        "payload_inertia": OutputVar("VECTOR6D", _zeros6, (5, 11), (3, 15)),
        "script_control_line": OutputVar("UINT32", lambda c: 0),
        "ft_raw_wrench": OutputVar("VECTOR6D", lambda c: c.meas.wrench_flange, (5, 9), None),
        "joint_position_deviation_ratio": OutputVar("DOUBLE", lambda c: 0.0, (5, 8), None),
        "collision_detection_ratio": OutputVar("DOUBLE", lambda c: 0.0, (5, 8), None),
        "time_scale_source": OutputVar("UINT32", lambda c: 0, (5, 8), None),
    }


def _register_outputs() -> dict[str, OutputVar]:
    """The general-purpose registers: int and double registers 0-47 (24-47 since 5.3 / 3.9),
    bit registers 64-127, both directions."""
    t: dict[str, OutputVar] = {}
    for i in range(48):
        since = ((5, 3), (3, 9)) if i >= 24 else ((5, 0), (3, 4))
        t[f"output_int_register_{i}"] = OutputVar("INT32", _register("output_int", i), *since)
        t[f"output_double_register_{i}"] = OutputVar(
            "DOUBLE", _register("output_double", i), *since
        )
        t[f"input_int_register_{i}"] = OutputVar("INT32", _register("input_int", i), *since)
        t[f"input_double_register_{i}"] = OutputVar("DOUBLE", _register("input_double", i), *since)
    for i in range(64, 128):
        t[f"output_bit_register_{i}"] = OutputVar("BOOL", _bit_register("output_bits", i))
        t[f"input_bit_register_{i}"] = OutputVar("BOOL", _bit_register("input_bits", i))
    return t


def _output_table() -> dict[str, OutputVar]:
    """Every RTDE output variable the twin serves, by name, in the controller's order."""
    return {
        **_motion_outputs(),
        **_status_outputs(),
        **_io_outputs(),
        **_misc_outputs(),
        **_register_outputs(),
    }


def _input_table() -> dict[str, str]:
    t = {
        "standard_digital_output_mask": "UINT8",
        "standard_digital_output": "UINT8",
        "configurable_digital_output_mask": "UINT8",
        "configurable_digital_output": "UINT8",
        "tool_digital_output_mask": "UINT8",
        "tool_digital_output": "UINT8",
        "speed_slider_mask": "UINT32",
        "speed_slider_fraction": "DOUBLE",
        "standard_analog_output_mask": "UINT8",
        "standard_analog_output_type": "UINT8",
        "standard_analog_output_0": "DOUBLE",
        "standard_analog_output_1": "DOUBLE",
        "input_bit_registers0_to_31": "UINT32",
        "input_bit_registers32_to_63": "UINT32",
        "external_force_torque": "VECTOR6D",
    }
    for i in range(48):
        t[f"input_int_register_{i}"] = "INT32"
        t[f"input_double_register_{i}"] = "DOUBLE"
    for i in range(64, 128):
        t[f"input_bit_register_{i}"] = "BOOL"
    return t


OUTPUTS = _output_table()
INPUTS = _input_table()


def output_type(name: str, versions: tuple[int, ...]) -> str:
    """The RTDE type of output ``name`` on a controller of ``versions``, or NOT_FOUND."""
    var = OUTPUTS.get(name)
    if var is None:
        return "NOT_FOUND"
    major, minor = versions[0], versions[1]
    since = var.min_cb3 if major < 5 else var.min_e
    if since is None or (major, minor) < since:
        return "NOT_FOUND"
    return var.type


@dataclass
class _OutputRecipe:
    recipe_id: int
    getters: list[tuple[Callable[[Controller], Any], bool]]  # (getter, is_vector)
    packer: struct.Struct
    ratio: float  # packages per controller period
    phase: float = 1.0  # first package at once


@dataclass
class _InputRecipe:
    recipe_id: int
    names: list[str]
    types: list[str]
    unpacker: struct.Struct


class InputOwners:
    """Which session writes which input field (an input has one writer at a time)."""

    def __init__(self) -> None:
        self._owner: dict[str, int] = {}

    def claim(self, session_id: int, names: list[str]) -> list[str]:
        """Names already owned by another session; claims the rest when none is."""
        taken = [n for n in names if self._owner.get(n, session_id) != session_id]
        if not taken:
            for n in names:
                self._owner[n] = session_id
        return taken

    def release(self, session_id: int) -> None:
        for name in [n for n, s in self._owner.items() if s == session_id]:
            del self._owner[name]


class RtdeError(Exception):
    """The peer broke the protocol; the connection is closed."""


class RtdeSession:
    """One RTDE connection's protocol state (no socket)."""

    def __init__(self, session_id: int, ctl: Controller, owners: InputOwners) -> None:
        self.session_id = session_id
        self.ctl = ctl
        self.owners = owners
        self.protocol_version = 1
        self.started = False
        self.outputs: list[_OutputRecipe] = []
        self.inputs: dict[int, _InputRecipe] = {}
        # output and input recipes are numbered separately, each from 1 (clients rely on it)
        self._next_id = {"out": 1, "in": 1}
        self._buffer = bytearray()
        self.messages: list[str] = []

    # -- incoming

    def feed(self, data: bytes) -> list[bytes]:
        """Consume received bytes (any split); return the reply messages to send."""
        self._buffer += data
        replies: list[bytes] = []
        while len(self._buffer) >= HEADER.size:
            size, kind = HEADER.unpack_from(self._buffer)
            if size < HEADER.size:
                raise RtdeError(f"bad RTDE message size {size}")
            if len(self._buffer) < size:
                break
            payload = bytes(self._buffer[HEADER.size : size])
            del self._buffer[:size]
            reply = self._handle(kind, payload)
            if reply is not None:
                replies.append(reply)
        return replies

    @staticmethod
    def message(kind: int, payload: bytes = b"") -> bytes:
        return HEADER.pack(HEADER.size + len(payload), kind) + payload

    def _handle(self, kind: int, payload: bytes) -> bytes | None:
        if kind == V:
            (version,) = struct.unpack(">H", payload[:2])
            accepted = version in (1, 2)
            if accepted:
                self.protocol_version = version
            return self.message(V, struct.pack(">B", int(accepted)))
        if kind == v:
            return self.message(v, struct.pack(">IIII", *self.ctl.versions))
        if kind == O:
            return self._setup_outputs(payload)
        if kind == I:
            return self._setup_inputs(payload)
        if kind == S:
            self.started = True
            return self.message(S, struct.pack(">B", 1))
        if kind == P:
            self.started = False
            return self.message(P, struct.pack(">B", 1))
        if kind == U:
            self._data(payload)
            return None
        if kind == M:
            self.messages.append(payload.decode("latin-1", "replace"))
            return None
        raise RtdeError(f"unknown RTDE message type {kind}")

    def _setup_outputs(self, payload: bytes) -> bytes:
        if self.protocol_version >= 2:
            (frequency,) = struct.unpack(">d", payload[:8])
            names = [n for n in payload[8:].decode("ascii", "replace").split(",") if n]
        else:
            frequency, names = self.ctl.spec.rate_hz, [n for n in payload.decode().split(",") if n]
        with self.ctl.lock:
            versions = self.ctl.versions
        types = [output_type(n, versions) for n in names]
        frequency = min(frequency, self.ctl.spec.rate_hz)  # never faster than the controller
        if not names or "NOT_FOUND" in types or not frequency > 0:
            return self.message(O, struct.pack(">B", 0) + ",".join(types).encode())
        recipe_id = self._new_recipe_id("out")
        fmt = ">" + "".join(_FORMATS[t] for t in types)
        getters = [(OUTPUTS[n].get, t in _VECTOR) for n, t in zip(names, types, strict=True)]
        self.outputs.append(
            _OutputRecipe(recipe_id, getters, struct.Struct(fmt), frequency / self.ctl.spec.rate_hz)
        )
        return self.message(O, struct.pack(">B", recipe_id) + ",".join(types).encode())

    def _setup_inputs(self, payload: bytes) -> bytes:
        names = [n for n in payload.decode("ascii", "replace").split(",") if n]
        types = [INPUTS.get(n, "NOT_FOUND") for n in names]
        if not names or "NOT_FOUND" in types:
            return self.message(I, struct.pack(">B", 0) + ",".join(types).encode())
        taken = set(self.owners.claim(self.session_id, names))
        if taken:
            types = ["IN_USE" if n in taken else t for n, t in zip(names, types, strict=True)]
            return self.message(I, struct.pack(">B", 0) + ",".join(types).encode())
        recipe_id = self._new_recipe_id("in")
        fmt = ">" + "".join(_FORMATS[t] for t in types)
        self.inputs[recipe_id] = _InputRecipe(recipe_id, names, types, struct.Struct(fmt))
        return self.message(I, struct.pack(">B", recipe_id) + ",".join(types).encode())

    def _new_recipe_id(self, kind: str) -> int:
        recipe_id = self._next_id[kind]
        self._next_id[kind] = recipe_id % 255 + 1
        return recipe_id

    def _data(self, payload: bytes) -> None:
        if not payload:
            return
        if self.protocol_version >= 2:
            recipe, offset = self.inputs.get(payload[0]), 1
        else:  # version 1: one input recipe, no id byte
            recipe, offset = next(iter(self.inputs.values()), None), 0
        if recipe is None or len(payload) - offset < recipe.unpacker.size:
            return
        values = recipe.unpacker.unpack_from(payload, offset)
        fields: dict[str, Any] = {}
        k = 0
        for name, type_ in zip(recipe.names, recipe.types, strict=True):
            width = (
                6
                if type_ in ("VECTOR6D", "VECTOR6INT32", "VECTOR6UINT32")
                else 3
                if type_ == "VECTOR3D"
                else 1
            )
            fields[name] = values[k] if width == 1 else list(values[k : k + width])
            k += width
        with self.ctl.lock:
            apply_input_package(self.ctl, fields)

    def close(self) -> None:
        self.owners.release(self.session_id)

    # -- outgoing

    def output_packets(self) -> list[bytes]:
        """Data packages due this controller period (call under the controller lock)."""
        if not self.started:
            return []
        packets = []
        for recipe in self.outputs:
            recipe.phase += recipe.ratio
            if recipe.phase < 1.0 - 1e-9:
                continue
            recipe.phase -= 1.0
            values: list[Any] = []
            for get, is_vector in recipe.getters:
                value = get(self.ctl)
                if is_vector:
                    values.extend(value)
                else:
                    values.append(value)
            head = bytes([recipe.recipe_id]) if self.protocol_version >= 2 else b""
            packets.append(self.message(U, head + recipe.packer.pack(*values)))
        return packets
