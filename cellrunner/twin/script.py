"""Programs the virtual controller runs from its script ports (30001-30003).

We do not interpret URScript in general. Two kinds of program are recognised:

- **ur_rtde's control script** (``def rtde_control():`` with its ``rtde_cmd`` /
  ``process_cmd`` loop): :class:`RtdeControlProgram` implements its register protocol.
  Each controller period it reads the command in ``input_int_register_<off>+0``, the
  arguments in ``input_double_register_<off>+0..`` and ``input_int_register_<off>+1``,
  and answers in ``output_int_register_<off>+0`` (1 ready for a command, 2 done with
  it), ``output_int_register_<off>+1`` / ``output_double_register_<off>+0..`` (results)
  and ``output_int_register_<off>+2`` (async progress: running bit 15, progress in bits
  0-14, a write counter in bits 16-22, the operation id in bits 24-30). Real-time
  commands (servoj, speedj, ...) answer "ready" in the same period; the others answer
  "done" once finished (a synchronous move when the arm arrives) and "ready" again once
  the client has cleared the command register. ``<off>`` is the register offset ur_rtde
  injects (0, or 24 for the upper range). Paths (``moveJ(path)``, ``moveL(path)``,
  ``movePath``) arrive as movej/movel lines injected after ``# inject move path``.
- **simple programs**: a ``def``/``sec`` block or a single line made only of
  ``movej``/``movel``/``stopj``/``stopl``, digital output setters,
  ``write_output_*_register``, ``set_tcp``, ``set_payload``, ``sleep``, ``textmsg``,
  ``popup`` and ``protective_stop`` statements with literal arguments (what
  ``sendCustomScriptFunction`` and hand-written one-liners usually hold). Anything else
  is refused, as a controller refuses a program that does not compile, and logged.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin import rtde_queries as Q
from cellrunner.twin.controller import Controller
from cellrunner.twin.kinematics import pose_to_matrix
from cellrunner.twin.moves import build_path_motion, movej, movel
from cellrunner.twin.script_text import PathEntry, ScriptError, parse_move_path
from cellrunner.twin.simple_program import SimpleProgram

__all__ = [
    "DONE",
    "READY",
    "REALTIME_COMMANDS",
    "RtdeControlProgram",
    "ScriptError",
    "parse_program",
]

REALTIME_COMMANDS = frozenset({24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71})
READY, DONE = 1, 2


def parse_program(text: str) -> tuple[str, Any]:
    """Recognise one uploaded program: ``("rtde_control", RtdeControlProgram)`` or
    ``("simple", SimpleProgram)``; raises :class:`ScriptError` for anything else."""
    if "def rtde_cmd():" in text and "def process_cmd(cmd):" in text:
        return "rtde_control", RtdeControlProgram.from_text(text)
    return "simple", SimpleProgram.from_text(text)


# --------------------------------------------------------------------------- ur_rtde


@dataclass
class RtdeControlProgram:
    """ur_rtde's control script, by its register protocol (see the module docstring)."""

    reg_offset_int: int = 0
    reg_offset_float: int = 0
    path: list[PathEntry] = field(default_factory=list)
    name: str = "rtde_control"
    executing_cmd: bool = False
    busy: Any = None  # the motion a synchronous command waits for
    async_motion: Any = None
    async_wr_count: int = 0
    async_op_id: int = 0
    last_progress: int = -1
    started: bool = False
    force_mode_damping: float = 0.025
    force_mode_gain_scaling: float = 0.5

    @classmethod
    def from_text(cls, text: str) -> RtdeControlProgram:
        def offset(tag: str) -> int:
            m = re.search(re.escape(tag) + r"\s*(\d+)", text)
            return int(m.group(1)) if m else 0

        return cls(
            reg_offset_int=offset("# int register offset\n"),
            reg_offset_float=offset("# float register offset\n"),
            path=parse_move_path(text),
        )

    # registers, offset as the script's read_input_*_reg / write_output_*_reg do
    def in_int(self, ctl: Controller, i: int) -> int:
        return ctl.reg.input_int[i + self.reg_offset_int]

    def in_double(self, ctl: Controller, i: int) -> float:
        return ctl.reg.input_double[i + self.reg_offset_float]

    def in_q(self, ctl: Controller, i: int) -> np.ndarray:
        return np.array([self.in_double(ctl, i + k) for k in range(6)])

    def out_int(self, ctl: Controller, i: int, value: int) -> None:
        ctl.reg.output_int[i + self.reg_offset_int] = int(value)

    def out_double(self, ctl: Controller, i: int, value: float) -> None:
        ctl.reg.output_double[i + self.reg_offset_float] = float(value)

    def out_q(self, ctl: Controller, i: int, values: np.ndarray) -> None:
        for k, v in enumerate(values):
            self.out_double(ctl, i + k, float(v))

    def _write_async(self, ctl: Controller, value: int) -> None:
        self.async_wr_count = (self.async_wr_count + 1) % 128
        if value == 0:
            self.async_op_id = (self.async_op_id + 1) % 128
        reg = self.async_wr_count * 65536 + self.async_op_id * 16777216
        if value >= 0:
            reg += min(value, 32767) + 32768
        self.out_int(ctl, 2, reg)

    # the main loop, one iteration per controller period (the script's sync())
    def tick(self, ctl: Controller) -> bool:
        if not self.started:
            self.started = True
            self._write_async(ctl, -1)
            self.out_int(ctl, 0, READY)
        self._track_async(ctl)
        if self.busy is not None:
            if ctl.motion is self.busy:
                self._track_progress(ctl, self.busy)
                return True
            self.busy = None
            self.out_int(ctl, 0, DONE)
            return True
        cmd = self.in_int(ctl, 0)
        if cmd in REALTIME_COMMANDS:
            self.process(ctl, cmd)
            self.out_int(ctl, 0, READY)
        elif cmd == 0:
            self.executing_cmd = False
            self.out_int(ctl, 0, READY)
        elif not self.executing_cmd:
            self.executing_cmd = True
            if not self.process(ctl, cmd):
                return False
            if self.busy is None:
                self.out_int(ctl, 0, DONE)
        return True

    def kill(self, ctl: Controller) -> None:
        self.busy = None
        self.async_motion = None

    def _track_progress(self, ctl: Controller, motion: Any) -> None:
        progress = getattr(motion, "progress", None)
        if progress is not None and progress != self.last_progress:
            self.last_progress = progress
            self._write_async(ctl, progress)

    def _track_async(self, ctl: Controller) -> None:
        if self.async_motion is None:
            return
        if ctl.motion is not self.async_motion:
            self.async_motion = None
            self._write_async(ctl, -1)
        else:
            self._track_progress(ctl, self.async_motion)

    def _stop_async_move(self, ctl: Controller) -> None:
        if self.async_motion is not None:
            if ctl.motion is self.async_motion:
                ctl.motion = None
            self.async_motion = None
            self._write_async(ctl, -1)

    def _start(self, ctl: Controller, motion: Any, asynchronous: bool) -> None:
        ctl.start_motion(motion)
        if asynchronous:
            self.async_motion = motion
            self.last_progress = -1
            self._write_async(ctl, 0)
        else:
            self.busy = motion

    def process(self, ctl: Controller, cmd: int) -> bool:
        """Execute command ``cmd``; False for the stop-script command (255)."""
        try:
            handler = _HANDLERS.get(cmd)
            if cmd == 255:
                ctl.add_log("Received stop script!")
                return False
            if handler is None:
                ctl.add_log(f"rtde_control: command {cmd} not supported by the twin")
                return True
            handler(self, ctl)
        except mo.MotionError as exc:
            ctl.add_log(str(exc))
            ctl.stop_program()
        return True

    # --- command handlers (numbers as ur_rtde's RobotCommand::Type) ---

    def _movej(self, ctl: Controller) -> None:
        q = self.in_q(ctl, 0)
        self._move_joints(ctl, q)

    def _move_joints(self, ctl: Controller, q: np.ndarray) -> None:
        v, a, asynchronous = (
            self.in_double(ctl, 6),
            self.in_double(ctl, 7),
            self.in_int(ctl, 1) == 1,
        )
        self._stop_async_move(ctl)
        self._start(ctl, movej(ctl, q, v, a), asynchronous)

    def _movej_ik(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self.in_q(ctl, 0)), ctl.target_q)
        if q is None:
            raise mo.MotionError("get_inverse_kin: no solution")
        self._move_joints(ctl, q)

    def _movel(self, ctl: Controller) -> None:
        self._move_line(ctl, self.in_q(ctl, 0))

    def _movel_fk(self, ctl: Controller) -> None:
        self._move_line(ctl, ctl.kinematics.tcp_pose(self.in_q(ctl, 0)))

    def _move_line(self, ctl: Controller, pose: np.ndarray) -> None:
        v, a, asynchronous = (
            self.in_double(ctl, 6),
            self.in_double(ctl, 7),
            self.in_int(ctl, 1) == 1,
        )
        self._stop_async_move(ctl)
        self._start(ctl, movel(ctl, pose, v, a), asynchronous)

    def _move_path(self, ctl: Controller) -> None:
        asynchronous = self.in_int(ctl, 1) == 1
        self._stop_async_move(ctl)
        if not self.path:
            ctl.add_log("exec_move_path: empty path")
            return
        self.last_progress = -1
        self._start(ctl, build_path_motion(ctl, self.path), asynchronous)

    def _servoj(self, ctl: Controller) -> None:
        self._servo_to(ctl, self.in_q(ctl, 0))

    def _servol(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self.in_q(ctl, 0)), ctl.target_q, iterations=20)
        if q is None:
            raise mo.MotionError("servol: no inverse kinematics solution")
        self._servo_to(ctl, q)

    def servo_target(self, ctl: Controller) -> np.ndarray | None:
        """The joint target (rad) of a servoJ command standing in the input registers."""
        return self.in_q(ctl, 0) if self.in_int(ctl, 0) == 11 else None

    def _servo_to(self, ctl: Controller, q: np.ndarray) -> None:
        servo = ctl.motion
        if not isinstance(servo, mo.Servo):
            servo = ctl.start_motion(mo.Servo(ctl.qd_max, ctl.accel_max))
        servo.set_target(q, self.in_double(ctl, 8), self.in_double(ctl, 9), self.in_double(ctl, 10))

    def _speedj(self, ctl: Controller) -> None:
        qd, a = self.in_q(ctl, 0), self.in_double(ctl, 6)
        if isinstance(ctl.motion, mo.SpeedJ):
            ctl.motion.qd_target, ctl.motion.accel = qd, a
        else:
            ctl.start_motion(mo.SpeedJ(qd, a, ctl.qd_max))

    def _speedl(self, ctl: Controller) -> None:
        xd, a = self.in_q(ctl, 0), self.in_double(ctl, 6)
        if isinstance(ctl.motion, mo.SpeedL):
            ctl.motion.xd_target, ctl.motion.accel = xd, a
        else:
            ctl.start_motion(mo.SpeedL(xd, a, ctl.kinematics, ctl.qd_max))

    def _stop_with_decel(self, ctl: Controller) -> None:  # speedStop, servoStop
        self.busy = ctl.stop_motion(self.in_double(ctl, 0))

    def _stopl_stopj(self, ctl: Controller) -> None:
        decel, asynchronous = self.in_double(ctl, 0), self.in_int(ctl, 1) == 1
        self._stop_async_move(ctl)
        stop = ctl.stop_motion(decel)
        if asynchronous:
            self.async_motion = stop
            self._write_async(ctl, 0)
        else:
            self.busy = stop

    def _force_mode_stop(self, ctl: Controller) -> None:
        self.busy = ctl.stop_motion(10.0)

    def _zero_ft(self, ctl: Controller) -> None:
        ctl.zero_ft_sensor()

    def _set_payload(self, ctl: Controller) -> None:
        ctl.payload_kg = self.in_double(ctl, 0)
        cog = np.array([self.in_double(ctl, i) for i in (1, 2, 3)])
        if np.any(cog != 0):
            ctl.payload_cog_m = cog

    def _set_tcp(self, ctl: Controller) -> None:
        ctl.set_tcp(self.in_q(ctl, 0))

    def _protective_stop(self, ctl: Controller) -> None:
        ctl.protective_stop("protective_stop() called by the program")

    def _set_watchdog(self, ctl: Controller) -> None:
        frequency = self.in_double(ctl, 0)
        register = "input_int_register_24" if self.reg_offset_int == 24 else "input_int_register_0"
        ctl.watchdog = (register, frequency) if frequency > 0 else None
        ctl.last_input_write[register] = ctl.time_s

    def _move_until_contact(self, ctl: Controller) -> None:
        xd, acc = self.in_q(ctl, 0), self.in_double(ctl, 12)
        self._stop_async_move(ctl)
        speed = mo.SpeedL(xd, acc or 0.5, ctl.kinematics, ctl.qd_max)
        self.busy = ctl.start_motion(mo.UntilContact(speed, ctl.tool_contact))

    def _jog_start(self, ctl: Controller) -> None:
        xd = self.in_q(ctl, 0)
        if round(self.in_double(ctl, 6)) == 1:  # tool feature: speeds in the TCP frame
            R = pose_to_matrix(ctl.target_tcp_pose)[:3, :3]
            xd = np.concatenate([R @ xd[:3], R @ xd[3:]])
        if isinstance(ctl.motion, mo.SpeedL):
            ctl.motion.xd_target = xd
        else:
            ctl.start_motion(
                mo.SpeedL(xd, self.in_double(ctl, 7) or 0.5, ctl.kinematics, ctl.qd_max)
            )

    def _jog_stop(self, ctl: Controller) -> None:
        self.busy = ctl.stop_motion(1.2)

    def _damping(self, ctl: Controller) -> None:
        self.force_mode_damping = self.in_double(ctl, 0)

    def _gain_scaling(self, ctl: Controller) -> None:
        self.force_mode_gain_scaling = self.in_double(ctl, 0)

    def _unsupported(self, ctl: Controller) -> None:
        ctl.add_log(
            f"rtde_control: command {self.in_int(ctl, 0)} accepted but not simulated by the twin"
        )


P = RtdeControlProgram
_HANDLERS: dict[int, Callable[[RtdeControlProgram, Controller], None]] = {
    1: P._movej, 2: P._movej_ik, 3: P._movel, 4: P._movel_fk,
    6: P._unsupported, 7: P._force_mode_stop, 8: P._zero_ft,
    9: P._speedj, 10: P._speedl, 11: P._servoj, 12: P._unsupported,
    15: P._stop_with_decel, 16: P._stop_with_decel, 17: P._set_payload,
    18: P._unsupported, 19: P._unsupported, 20: P._damping, 21: P._gain_scaling,
    24: P._servol, 25: Q.tool_contact, 26: Q.steptime, 27: Q.joint_history,
    28: Q.target_waypoint, 29: P._set_tcp, 30: Q.ik_args, 31: P._protective_stop,
    33: P._stopl_stopj, 34: P._stopl_stopj, 35: P._set_watchdog,
    36: Q.pose_within_limits, 37: Q.joints_within_limits, 38: Q.joint_torques,
    39: Q.pose_trans, 40: Q.tcp_offset, 41: P._jog_start, 42: P._jog_stop,
    43: Q.fk_default, 44: Q.fk_args, 45: P._move_path, 46: Q.ik_default,
    47: Q.is_steady, 51: P._move_until_contact, 52: P._unsupported, 53: P._unsupported,
    54: Q.freedrive_status, 56: P._unsupported, 57: P._unsupported, 58: Q.flange_pose,
    59: P._unsupported, 60: Q.ik_has_solution, 61: Q.ik_has_solution,
    62: P._unsupported, 63: P._unsupported, 64: Q.read_contact, 65: P._set_payload,
}  # fmt: skip
