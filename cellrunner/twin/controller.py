"""The controller core of the virtual UR: modes, safety, program, IO and registers.

One :class:`Controller` is one robot cabinet. Network servers (``twin.server``) and the
fault channel call its methods under :attr:`Controller.lock`; the real-time loop calls
:meth:`Controller.tick` once per period (2 ms e-Series, 8 ms CB3), which runs the loaded
program one step, advances the motion generator, steps the physics and checks safety.

State follows UR's numbering (RTDE ``robot_mode``, ``safety_mode``, ``runtime_state``):

- power and brakes: POWER_OFF -> ``power_on()`` -> (BOOTING) -> IDLE -> ``brake_release()``
  -> RUNNING; only RUNNING with safety NORMAL moves and runs programs.
- protective stop (on request, on collision reported by the physics): the arm stops,
  the program is stopped, ``unlock_protective_stop()`` is refused until
  ``unlock_delay_s`` (5 s) after the stop.
- e-stop press: arm stops, program stopped, power off; release brings safety back to
  NORMAL with the arm still off (power on and brake release again).
"""

from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from cellrunner.model.robots import RobotSpec
from cellrunner.twin import motion as mo
from cellrunner.twin.kinematics import Kinematics
from cellrunner.twin.modes import RobotMode as RobotMode
from cellrunner.twin.modes import RuntimeState as RuntimeState
from cellrunner.twin.modes import SafetyMode as SafetyMode
from cellrunner.twin.physics import KinematicPhysics, Measurement, Physics
from cellrunner.twin.pulse_decoder import PulseDecoders
from cellrunner.twin.setpoint import advance_motion, pose_rate
from cellrunner.twin.watchdog import check_watchdog

DEFAULT_VERSIONS = {"e-Series": (5, 11, 1, 108318), "CB3": (3, 15, 7, 106331)}
UNLOCK_REFUSED = (
    "Cannot unlock protective stop until 5s after occurrence. "
    "Always inspect cause of protective stop before unlocking"
)


class Program(Protocol):
    """A running URScript program (see ``twin.script``)."""

    name: str

    def tick(self, ctl: Controller) -> bool:
        """Run one controller period; False when the program has ended."""

    def kill(self, ctl: Controller) -> None:
        """The program is being stopped from outside (stop, safety, new program)."""


@dataclass
class ControllerConfig:
    """Identity and timing of a virtual controller."""

    spec: RobotSpec
    versions: tuple[int, int, int, int] | None = None  # None: by generation
    serial_number: str = "20215500001"
    q_initial_rad: tuple[float, ...] = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)
    unlock_delay_s: float = 5.0
    power_on_s: float = 0.3
    brake_release_s: float = 0.3
    start_running: bool = True  # powered and brakes released at start
    remote_control: bool = True
    protective_stop_decel_rad_s2: float = 20.0

    @property
    def controller_versions(self) -> tuple[int, int, int, int]:
        return self.versions or DEFAULT_VERSIONS[self.spec.generation]

    @property
    def period_s(self) -> float:
        return 1.0 / self.spec.rate_hz


@dataclass
class _Registers:
    input_int: list[int] = field(default_factory=lambda: [0] * 48)
    input_double: list[float] = field(default_factory=lambda: [0.0] * 48)
    input_bits: int = 0  # 128 bits
    output_int: list[int] = field(default_factory=lambda: [0] * 48)
    output_double: list[float] = field(default_factory=lambda: [0.0] * 48)
    output_bits: int = 0


class Controller:
    """A virtual UR controller; construct, then drive :meth:`tick` from a real-time loop."""

    def __init__(self, config: ControllerConfig, physics: Physics | None = None) -> None:
        self.config = config
        self.spec = config.spec
        self.period_s = config.period_s
        self.physics: Physics = physics if physics is not None else KinematicPhysics(config.spec)
        self.kinematics = Kinematics(config.spec)
        self.lock = threading.RLock()
        self.qd_max = np.radians(np.array(self.spec.joint_speed_max_deg_s, dtype=float))
        self.accel_max = float(np.radians(self.spec.joint_accel_max_deg_s2))
        self.reg = _Registers()
        self.log: collections.deque[str] = collections.deque(maxlen=500)
        self.pulse_decoders = PulseDecoders()  # conveyor encoders (SPEC 13)
        # modes
        self.robot_mode = RobotMode.RUNNING if config.start_running else RobotMode.POWER_OFF
        self.safety_mode = SafetyMode.NORMAL
        self.runtime_state = RuntimeState.STOPPED
        self.remote_control = config.remote_control
        self.estop_pressed = False
        self.protective_stop_time: float | None = None  # controller time of the last stop
        self.protective_stop_reason = ""
        self.popup: str | None = None
        self.safety_popup: str | None = None
        self.loaded_program = ""
        self._mode_timer: tuple[float, RobotMode] | None = None
        # program and motion
        self.program: Program | None = None
        self.programs_started = 0
        self.motion: Any = None
        self.speed_slider = 1.0
        self.servo_record: list[tuple[float, ...]] | None = (
            None  # (time_s, q1..q6 rad) per servoJ package
        )
        # IO image
        self.standard_do = 0  # DO0-7
        self.configurable_do = 0  # CO0-7
        self.tool_do = 0  # TO0-1
        self.analog_out = [0.0, 0.0]
        self.analog_out_types = 0
        self.input_overrides: dict[int, bool] = {}
        # tool and payload
        self.tcp_offset = np.zeros(6)
        self.payload_kg = 0.0
        self.payload_cog_m = np.zeros(3)
        self.ft_offset = np.zeros(6)
        self.external_ft = np.zeros(6)
        # watchdog: (register name, min frequency, last write time)
        self.watchdog: tuple[str, float] | None = None
        self.last_input_write: dict[str, float] = {}
        # time and kinematic state
        self.time_s = 0.0
        self.tick_count = 0
        self.wall_start = time.monotonic()
        q0 = np.array(config.q_initial_rad, dtype=float)
        self.physics.reset(q0)
        self.target_q = q0.copy()
        self.target_qd = np.zeros(6)
        self.target_qdd = np.zeros(6)
        self.meas: Measurement = self.physics.measure()
        self.actual_tcp_pose = self.kinematics.tcp_pose(q0)
        self.target_tcp_pose = self.actual_tcp_pose.copy()
        self.actual_tcp_speed = np.zeros(6)
        self.target_tcp_speed = np.zeros(6)

    # ------------------------------------------------------------------ queries

    @property
    def versions(self) -> tuple[int, int, int, int]:
        return self.config.controller_versions

    @property
    def can_move(self) -> bool:
        return self.robot_mode == RobotMode.RUNNING and self.safety_mode == SafetyMode.NORMAL

    @property
    def digital_input_bits(self) -> int:
        bits = self.meas.digital_inputs
        for bit, value in self.input_overrides.items():
            bits = bits | (1 << bit) if value else bits & ~(1 << bit)
        return bits

    @property
    def digital_output_bits(self) -> int:
        return self.standard_do | self.configurable_do << 8 | self.tool_do << 16

    @property
    def wrench(self) -> np.ndarray:
        """``actual_TCP_force``: the flange wrench minus the zeroing offset (N, N m)."""
        return self.meas.wrench_flange - self.ft_offset

    def seconds_since_protective_stop(self) -> float | None:
        return (
            None if self.protective_stop_time is None else self.time_s - self.protective_stop_time
        )

    def add_log(self, text: str) -> None:
        self.log.append(f"{self.time_s:10.3f} {text}")

    # ------------------------------------------------------------------ power and brakes

    def power_on(self) -> None:
        if self.estop_pressed or self.safety_mode != SafetyMode.NORMAL:
            self.add_log("power on ignored: safety not normal")
            return
        if self.robot_mode in (RobotMode.POWER_OFF, RobotMode.BOOTING):
            self.robot_mode = RobotMode.BOOTING
            self._mode_timer = (self.time_s + self.config.power_on_s, RobotMode.IDLE)

    def power_off(self) -> None:
        self._halt_program("power off")
        self.robot_mode = RobotMode.POWER_OFF
        self._mode_timer = None

    def brake_release(self) -> None:
        if self.robot_mode == RobotMode.POWER_OFF and not self.estop_pressed:
            self.power_on()
        if self.robot_mode in (RobotMode.IDLE, RobotMode.POWER_ON, RobotMode.BOOTING):
            due = max(self.time_s, self._mode_timer[0] if self._mode_timer else self.time_s)
            self._mode_timer = (due + self.config.brake_release_s, RobotMode.RUNNING)

    # ------------------------------------------------------------------ safety

    def protective_stop(self, reason: str) -> None:
        if self.safety_mode != SafetyMode.NORMAL:
            return
        self.safety_mode = SafetyMode.PROTECTIVE_STOP
        self.protective_stop_time = self.time_s
        self.protective_stop_reason = reason
        self.safety_popup = f"Protective stop: {reason}"
        self.add_log(f"protective stop: {reason}")
        self._halt_program("protective stop")
        self.motion = mo.Stop(self.config.protective_stop_decel_rad_s2)

    def unlock_protective_stop(self) -> str:
        """Dashboard ``unlock protective stop``; returns UR's reply text."""
        if self.safety_mode == SafetyMode.PROTECTIVE_STOP:
            since = self.seconds_since_protective_stop() or 0.0
            if since < self.config.unlock_delay_s:
                return UNLOCK_REFUSED
            self.safety_mode = SafetyMode.NORMAL
            self.safety_popup = None
            self.add_log("protective stop released")
        return "Protective stop releasing"

    def press_estop(self, system: bool = False) -> None:
        self.estop_pressed = True
        self.safety_mode = (
            SafetyMode.SYSTEM_EMERGENCY_STOP if system else SafetyMode.ROBOT_EMERGENCY_STOP
        )
        self.add_log("emergency stop pressed")
        self._halt_program("emergency stop")
        self.motion = None
        self.target_qd = np.zeros(6)
        self.robot_mode = RobotMode.POWER_OFF
        self._mode_timer = None

    def release_estop(self) -> None:
        if not self.estop_pressed:
            return
        self.estop_pressed = False
        self.safety_mode = SafetyMode.NORMAL
        self.add_log("emergency stop released")

    def raise_fault(self, violation: bool = False) -> None:
        self.safety_mode = SafetyMode.VIOLATION if violation else SafetyMode.FAULT
        self._halt_program("safety fault")
        self.robot_mode = RobotMode.POWER_OFF

    def restart_safety(self) -> None:
        if self.estop_pressed:
            return
        if self.safety_mode in (SafetyMode.FAULT, SafetyMode.VIOLATION, SafetyMode.PROTECTIVE_STOP):
            self.safety_mode = SafetyMode.NORMAL
            self.safety_popup = None
        self._halt_program("restart safety")
        self.robot_mode = RobotMode.POWER_OFF
        self._mode_timer = None

    # ------------------------------------------------------------------ programs

    def start_program(self, program: Program) -> bool:
        """Run ``program`` (replacing a running one); False when the robot cannot run it."""
        self._halt_program("new program")
        if not self.can_move or not self.remote_control:
            self.add_log(f"program {program.name!r} not started: robot not ready")
            return False
        self.program = program
        self.programs_started += 1
        self.runtime_state = RuntimeState.PLAYING
        self.add_log(f"program {program.name!r} started")
        return True

    def pause_program(self) -> bool:
        """Dashboard ``pause``: the arm stops, the program keeps its place."""
        if self.program is None or self.runtime_state != RuntimeState.PLAYING:
            return False
        self.runtime_state = RuntimeState.PAUSED
        if self.motion is not None and not isinstance(self.motion, mo.Stop):
            self.motion = mo.Stop(self.accel_max)
        return True

    def resume_program(self) -> bool:
        if self.program is None or self.runtime_state != RuntimeState.PAUSED or not self.can_move:
            return False
        self.runtime_state = RuntimeState.PLAYING
        return True

    def stop_program(self) -> None:
        """Dashboard ``stop`` or end of a program: the arm stops, runtime STOPPED."""
        self._halt_program("stopped")

    def _halt_program(self, why: str) -> None:
        program = self.program
        if program is not None:
            self.program = None
            program.kill(self)
            self.add_log(f"program {program.name!r} ended: {why}")
            self.watchdog = None
            if self.motion is not None and not isinstance(self.motion, mo.Stop):
                self.motion = mo.Stop(self.accel_max)
        self.runtime_state = RuntimeState.STOPPED

    # ------------------------------------------------------------------ IO

    def set_standard_outputs(self, mask: int, value: int) -> None:
        self.standard_do = (self.standard_do & ~mask | value & mask) & 0xFF

    def set_configurable_outputs(self, mask: int, value: int) -> None:
        self.configurable_do = (self.configurable_do & ~mask | value & mask) & 0xFF

    def set_tool_outputs(self, mask: int, value: int) -> None:
        self.tool_do = (self.tool_do & ~mask | value & mask) & 0x03

    # ------------------------------------------------------------------ motion helpers

    def set_tcp(self, pose: np.ndarray) -> None:
        self.tcp_offset = np.asarray(pose, float)
        self.kinematics.set_tcp(self.tcp_offset)

    def zero_ft_sensor(self) -> None:
        self.ft_offset = self.meas.wrench_flange.copy()

    def start_motion(self, generator: Any) -> Any:
        self.motion = generator
        return generator

    def stop_motion(self, decel: float) -> mo.Stop:
        stop = mo.Stop(max(decel, 1e-3))
        self.motion = stop
        return stop

    def is_steady(self) -> bool:
        """At rest: measured and commanded joint speeds (almost) zero."""
        return bool(
            np.max(np.abs(self.meas.qd_rad_s)) < 1e-4 and np.max(np.abs(self.target_qd)) < 1e-4
        )

    def tool_contact(self, threshold_N: float = 10.0) -> bool:
        """The zeroed TCP force exceeds ``threshold_N`` (what ``tool_contact`` reports)."""
        return bool(np.linalg.norm(self.wrench[:3]) > threshold_N) or self.meas.contact

    # ------------------------------------------------------------------ the period

    def tick(self) -> None:
        """One controller period: program, motion, physics, safety. Hold the lock."""
        dt = self.period_s
        self.time_s += dt
        self.tick_count += 1
        if self._mode_timer is not None and self.time_s >= self._mode_timer[0]:
            mode = self._mode_timer[1]
            self._mode_timer = None
            self.robot_mode = mode
        check_watchdog(self)
        if self.runtime_state == RuntimeState.PAUSED:
            pass  # a paused program keeps its place and does not run
        elif self.program is not None and not self.program.tick(self):
            # a program that ends stops the arm (servo and speed threads end with it)
            self._halt_program("finished")
        advance_motion(self, dt)
        self.physics.apply_outputs(self.digital_output_bits)
        self.physics.step(self.target_q, dt)
        previous_tcp = self.actual_tcp_pose
        self.meas = self.physics.measure()
        self.pulse_decoders.update(self.physics, self.reg.output_int)
        self.actual_tcp_pose = self.kinematics.tcp_pose(self.meas.q_rad)
        self.actual_tcp_speed = pose_rate(previous_tcp, self.actual_tcp_pose, dt)
        if self.meas.contact and self.safety_mode == SafetyMode.NORMAL:
            what = self.meas.contact_what
            self.protective_stop(f"collision detected: {what}" if what else "collision detected")
