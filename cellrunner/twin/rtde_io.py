"""What the RTDE interface reads from the controller and writes into it, by field.

The controller (:mod:`cellrunner.twin.controller`) keeps its state; these are the RTDE
guide's views of it (status bits, joint modes) and the input packages a client sends
(registers, IO masks, the speed slider).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cellrunner.twin.controller import Controller, RobotMode, RuntimeState, SafetyMode

# safety_status_bits per safety mode (bit numbers from UR's RTDE guide)
SAFETY_BITS = {
    SafetyMode.NORMAL: 1 << 0,
    SafetyMode.REDUCED: 1 << 1,
    SafetyMode.PROTECTIVE_STOP: 1 << 2 | 1 << 10,
    SafetyMode.RECOVERY: 1 << 3,
    SafetyMode.SAFEGUARD_STOP: 1 << 4 | 1 << 10,
    SafetyMode.SYSTEM_EMERGENCY_STOP: 1 << 5 | 1 << 7 | 1 << 10,
    SafetyMode.ROBOT_EMERGENCY_STOP: 1 << 6 | 1 << 7 | 1 << 10,
    SafetyMode.VIOLATION: 1 << 8 | 1 << 10,
    SafetyMode.FAULT: 1 << 9 | 1 << 10,
}


def safety_status_bits(ctl: Controller) -> int:
    return SAFETY_BITS.get(ctl.safety_mode, 0)


def robot_status_bits(ctl: Controller) -> int:
    powered = ctl.robot_mode in (
        RobotMode.POWER_ON,
        RobotMode.IDLE,
        RobotMode.RUNNING,
        RobotMode.BACKDRIVE,
    )
    running = ctl.runtime_state == RuntimeState.PLAYING
    return int(powered) | int(running) << 1


def joint_mode(ctl: Controller) -> int:
    if ctl.robot_mode == RobotMode.RUNNING:
        return 253
    if ctl.robot_mode in (RobotMode.IDLE, RobotMode.POWER_ON):
        return 255
    return 239


def set_input_field(ctl: Controller, name: str, value: Any) -> None:
    """An RTDE input field by name (registers and IO commands); records the write."""
    ctl.last_input_write[name] = ctl.time_s
    kind, _, index = name.rpartition("_")
    if kind == "input_int_register":
        ctl.reg.input_int[int(index)] = int(value)
    elif kind == "input_double_register":
        ctl.reg.input_double[int(index)] = float(value)
    elif kind == "input_bit_register":
        bit = int(index)
        ctl.reg.input_bits = (
            ctl.reg.input_bits | (1 << bit) if value else ctl.reg.input_bits & ~(1 << bit)
        )
    elif name == "input_bit_registers0_to_31":
        ctl.reg.input_bits = ctl.reg.input_bits & ~0xFFFFFFFF | int(value)
    elif name == "input_bit_registers32_to_63":
        ctl.reg.input_bits = ctl.reg.input_bits & ~(0xFFFFFFFF << 32) | int(value) << 32
    elif name == "external_force_torque":
        ctl.external_ft = np.asarray(value, float)


def apply_input_package(ctl: Controller, fields: dict[str, Any]) -> None:
    """Masks and values of one RTDE input package (standard/configurable/tool IO...)."""
    if "standard_digital_output_mask" in fields:
        ctl.set_standard_outputs(
            fields["standard_digital_output_mask"], fields.get("standard_digital_output", 0)
        )
    if "configurable_digital_output_mask" in fields:
        ctl.set_configurable_outputs(
            fields["configurable_digital_output_mask"],
            fields.get("configurable_digital_output", 0),
        )
    if "tool_digital_output_mask" in fields:
        ctl.set_tool_outputs(
            fields["tool_digital_output_mask"], fields.get("tool_digital_output", 0)
        )
    if fields.get("speed_slider_mask", 0) & 1:
        ctl.speed_slider = min(1.0, max(0.0, float(fields.get("speed_slider_fraction", 1.0))))
    mask = fields.get("standard_analog_output_mask", 0)
    for i in range(2):
        if mask >> i & 1:
            ctl.analog_out[i] = float(fields.get(f"standard_analog_output_{i}", 0.0))
            bit = 1 << i
            types = fields.get("standard_analog_output_type", 0)
            ctl.analog_out_types = ctl.analog_out_types & ~bit | types & bit
    for name, value in fields.items():
        if name.startswith(("input_", "external_force_torque")):
            set_input_field(ctl, name, value)
    program = ctl.program
    if ctl.servo_record is not None and program is not None and hasattr(program, "servo_target"):
        q = program.servo_target(ctl)
        if q is not None:  # one row per servoJ package received (``record on``)
            ctl.servo_record.append((ctl.time_s, *(float(v) for v in q)))
