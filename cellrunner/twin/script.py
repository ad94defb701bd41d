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

import ast
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin.controller import Controller
from cellrunner.twin.kinematics import matrix_to_pose, pose_to_matrix

REALTIME_COMMANDS = frozenset({24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71})
READY, DONE = 1, 2
_INJECT_PATH = "# inject move path\n"


class ScriptError(ValueError):
    """A program the twin cannot run; the message names the offending statement."""


def parse_program(text: str) -> tuple[str, Any]:
    """Recognise one uploaded program: ``("rtde_control", RtdeControlProgram)`` or
    ``("simple", SimpleProgram)``; raises :class:`ScriptError` for anything else."""
    if "def rtde_cmd():" in text and "def process_cmd(cmd):" in text:
        return "rtde_control", RtdeControlProgram.from_text(text)
    return "simple", SimpleProgram.from_text(text)


# --------------------------------------------------------------------------- literals


def _literal(node: ast.AST) -> Any:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, bool, str)):
        return node.value
    if isinstance(node, ast.List):
        return [_literal(e) for e in node.elts]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _literal(node.operand)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
        left, right = _literal(node.left), _literal(node.right)
        ops: dict[type, Callable[[Any, Any], Any]] = {
            ast.Add: lambda a, b: a + b,
            ast.Sub: lambda a, b: a - b,
            ast.Mult: lambda a, b: a * b,
            ast.Div: lambda a, b: a / b,
        }
        return ops[type(node.op)](left, right)
    raise ScriptError(f"not a literal: {ast.unparse(node)}")


def _parse_call(line: str) -> tuple[str, list[Any], dict[str, Any]]:
    """``name(args, k=v)`` with literal arguments; URScript poses ``p[...]`` are lists."""
    source = re.sub(r"\bp\[", "[", line.strip())
    try:
        node = ast.parse(source, mode="eval").body
    except SyntaxError as exc:
        raise ScriptError(f"cannot parse: {line.strip()}") from exc
    if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Name):
        raise ScriptError(f"unsupported statement: {line.strip()}")
    args = [_literal(a) for a in node.args]
    kwargs = {k.arg: _literal(k.value) for k in node.keywords if k.arg}
    if re.search(r"\(\s*p\[", line):
        kwargs["_pose"] = True  # the first argument was a pose p[...], not joint angles
    return node.func.id, args, kwargs


# --------------------------------------------------------------------------- paths


@dataclass(frozen=True)
class PathEntry:
    """One injected path line: ``movej``/``movel`` to joints or a pose, with a, v, r."""

    kind: str  # "movej" | "movel"
    target: tuple[float, ...]
    is_pose: bool
    a: float
    v: float
    r: float
    progress: int  # the signal_async_progress index that precedes it


def parse_move_path(text: str) -> list[PathEntry]:
    """The movej/movel lines ur_rtde injected after ``# inject move path``."""
    start = text.find(_INJECT_PATH)
    if start < 0:
        return []
    entries: list[PathEntry] = []
    progress = 0
    for line in text[start + len(_INJECT_PATH) :].splitlines():
        stripped = line.strip()
        if stripped == "end":
            break
        if not stripped or stripped.startswith(("#", "textmsg")):
            continue
        name, args, kwargs = _parse_call(stripped)
        if name == "signal_async_progress":
            progress = int(args[0])
            continue
        if name not in ("movej", "movel", "movep"):
            raise ScriptError(f"unsupported path statement: {stripped}")
        is_pose = bool(re.search(r"\(\s*p\[", stripped))
        entries.append(
            PathEntry(
                "movej" if name == "movej" else "movel",
                tuple(float(x) for x in args[0]),
                is_pose,
                float(kwargs.get("a", 1.4 if name == "movej" else 1.2)),
                float(kwargs.get("v", 1.05 if name == "movej" else 0.25)),
                float(kwargs.get("r", 0.0)),
                progress,
            )
        )
    return entries


@dataclass
class Sequence:
    """Run motions one after another; each is built when the previous one ends."""

    factories: list[Callable[[np.ndarray], Any]]
    progress_of: list[list[int]]
    current: Any = None
    index: int = -1

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        if self.current is None:
            self.index += 1
            self.current = self.factories[self.index](q)
        q, qd, done = self.current.advance(q, qd, dt)
        if done:
            self.current = None
            return q, qd, self.index == len(self.factories) - 1
        return q, qd, False

    @property
    def progress(self) -> int:
        if self.index < 0:
            return self.progress_of[0][0] if self.progress_of and self.progress_of[0] else 0
        group = self.progress_of[self.index]
        seg = (
            getattr(self.current, "segment_index", len(group) - 1)
            if self.current is not None
            else len(group) - 1
        )
        return group[min(seg, len(group) - 1)]


def build_path_motion(ctl: Controller, entries: list[PathEntry]) -> Sequence:
    """Group consecutive movej / movel entries into blended paths, run in sequence."""
    groups: list[list[PathEntry]] = []
    for entry in entries:
        if groups and groups[-1][0].kind == entry.kind:
            groups[-1].append(entry)
        else:
            groups.append([entry])
    factories = [_path_factory(ctl, group) for group in groups]
    return Sequence(factories, [[e.progress for e in g] for g in groups])


def _path_factory(ctl: Controller, group: list[PathEntry]) -> Callable[[np.ndarray], Any]:
    def make(q_start: np.ndarray) -> Any:
        waypoints = []
        q_seed = q_start
        for e in group:
            target = np.array(e.target)
            if e.kind == "movej":
                if e.is_pose:
                    q_ik = ctl.kinematics.inverse(pose_to_matrix(target), q_seed)
                    if q_ik is None:
                        raise mo.MotionError(
                            f"movej: no inverse kinematics solution for p{list(e.target)}"
                        )
                    target = q_ik
                q_seed = target
            elif not e.is_pose:
                target = ctl.kinematics.tcp_pose(target)
            waypoints.append((target, e.v, e.a, e.r))
        cls = mo.JointPath if group[0].kind == "movej" else mo.LinearPath
        return cls(q_start, waypoints, ctl.kinematics, ctl.qd_max, ctl.speed_slider)

    return make


def movej(ctl: Controller, q: np.ndarray, v: float, a: float) -> mo.JointPath:
    return mo.JointPath(
        ctl.target_q,
        [(np.asarray(q, float), v, a, 0.0)],
        ctl.kinematics,
        ctl.qd_max,
        ctl.speed_slider,
    )


def movel(ctl: Controller, pose: np.ndarray, v: float, a: float) -> mo.LinearPath:
    return mo.LinearPath(
        ctl.target_q,
        [(np.asarray(pose, float), v, a, 0.0)],
        ctl.kinematics,
        ctl.qd_max,
        ctl.speed_slider,
    )


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
    def _in_int(self, ctl: Controller, i: int) -> int:
        return ctl.reg.input_int[i + self.reg_offset_int]

    def _in_double(self, ctl: Controller, i: int) -> float:
        return ctl.reg.input_double[i + self.reg_offset_float]

    def _in_q(self, ctl: Controller, i: int) -> np.ndarray:
        return np.array([self._in_double(ctl, i + k) for k in range(6)])

    def _out_int(self, ctl: Controller, i: int, value: int) -> None:
        ctl.reg.output_int[i + self.reg_offset_int] = int(value)

    def _out_double(self, ctl: Controller, i: int, value: float) -> None:
        ctl.reg.output_double[i + self.reg_offset_float] = float(value)

    def _out_q(self, ctl: Controller, i: int, values: np.ndarray) -> None:
        for k, v in enumerate(values):
            self._out_double(ctl, i + k, float(v))

    def _write_async(self, ctl: Controller, value: int) -> None:
        self.async_wr_count = (self.async_wr_count + 1) % 128
        if value == 0:
            self.async_op_id = (self.async_op_id + 1) % 128
        reg = self.async_wr_count * 65536 + self.async_op_id * 16777216
        if value >= 0:
            reg += min(value, 32767) + 32768
        self._out_int(ctl, 2, reg)

    # the main loop, one iteration per controller period (the script's sync())
    def tick(self, ctl: Controller) -> bool:
        if not self.started:
            self.started = True
            self._write_async(ctl, -1)
            self._out_int(ctl, 0, READY)
        self._track_async(ctl)
        if self.busy is not None:
            if ctl.motion is self.busy:
                self._track_progress(ctl, self.busy)
                return True
            self.busy = None
            self._out_int(ctl, 0, DONE)
            return True
        cmd = self._in_int(ctl, 0)
        if cmd in REALTIME_COMMANDS:
            self.process(ctl, cmd)
            self._out_int(ctl, 0, READY)
        elif cmd == 0:
            self.executing_cmd = False
            self._out_int(ctl, 0, READY)
        elif not self.executing_cmd:
            self.executing_cmd = True
            if not self.process(ctl, cmd):
                return False
            if self.busy is None:
                self._out_int(ctl, 0, DONE)
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
        q = self._in_q(ctl, 0)
        self._move_joints(ctl, q)

    def _move_joints(self, ctl: Controller, q: np.ndarray) -> None:
        v, a, asynchronous = (
            self._in_double(ctl, 6),
            self._in_double(ctl, 7),
            self._in_int(ctl, 1) == 1,
        )
        self._stop_async_move(ctl)
        self._start(ctl, movej(ctl, q, v, a), asynchronous)

    def _movej_ik(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), ctl.target_q)
        if q is None:
            raise mo.MotionError("get_inverse_kin: no solution")
        self._move_joints(ctl, q)

    def _movel(self, ctl: Controller) -> None:
        self._move_line(ctl, self._in_q(ctl, 0))

    def _movel_fk(self, ctl: Controller) -> None:
        self._move_line(ctl, ctl.kinematics.tcp_pose(self._in_q(ctl, 0)))

    def _move_line(self, ctl: Controller, pose: np.ndarray) -> None:
        v, a, asynchronous = (
            self._in_double(ctl, 6),
            self._in_double(ctl, 7),
            self._in_int(ctl, 1) == 1,
        )
        self._stop_async_move(ctl)
        self._start(ctl, movel(ctl, pose, v, a), asynchronous)

    def _move_path(self, ctl: Controller) -> None:
        asynchronous = self._in_int(ctl, 1) == 1
        self._stop_async_move(ctl)
        if not self.path:
            ctl.add_log("exec_move_path: empty path")
            return
        self.last_progress = -1
        self._start(ctl, build_path_motion(ctl, self.path), asynchronous)

    def _servoj(self, ctl: Controller) -> None:
        self._servo_to(ctl, self._in_q(ctl, 0))

    def _servol(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), ctl.target_q, iterations=20)
        if q is None:
            raise mo.MotionError("servol: no inverse kinematics solution")
        self._servo_to(ctl, q)

    def servo_target(self, ctl: Controller) -> np.ndarray | None:
        """The joint target (rad) of a servoJ command standing in the input registers."""
        return self._in_q(ctl, 0) if self._in_int(ctl, 0) == 11 else None

    def _servo_to(self, ctl: Controller, q: np.ndarray) -> None:
        servo = ctl.motion
        if not isinstance(servo, mo.Servo):
            servo = ctl.start_motion(mo.Servo(ctl.qd_max, ctl.accel_max))
        servo.set_target(
            q, self._in_double(ctl, 8), self._in_double(ctl, 9), self._in_double(ctl, 10)
        )

    def _speedj(self, ctl: Controller) -> None:
        qd, a = self._in_q(ctl, 0), self._in_double(ctl, 6)
        if isinstance(ctl.motion, mo.SpeedJ):
            ctl.motion.qd_target, ctl.motion.accel = qd, a
        else:
            ctl.start_motion(mo.SpeedJ(qd, a, ctl.qd_max))

    def _speedl(self, ctl: Controller) -> None:
        xd, a = self._in_q(ctl, 0), self._in_double(ctl, 6)
        if isinstance(ctl.motion, mo.SpeedL):
            ctl.motion.xd_target, ctl.motion.accel = xd, a
        else:
            ctl.start_motion(mo.SpeedL(xd, a, ctl.kinematics, ctl.qd_max))

    def _stop_with_decel(self, ctl: Controller) -> None:  # speedStop, servoStop
        self.busy = ctl.stop_motion(self._in_double(ctl, 0))

    def _stopl_stopj(self, ctl: Controller) -> None:
        decel, asynchronous = self._in_double(ctl, 0), self._in_int(ctl, 1) == 1
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
        ctl.payload_kg = self._in_double(ctl, 0)
        cog = np.array([self._in_double(ctl, i) for i in (1, 2, 3)])
        if np.any(cog != 0):
            ctl.payload_cog_m = cog

    def _set_tcp(self, ctl: Controller) -> None:
        ctl.set_tcp(self._in_q(ctl, 0))

    def _protective_stop(self, ctl: Controller) -> None:
        ctl.protective_stop("protective_stop() called by the program")

    def _set_watchdog(self, ctl: Controller) -> None:
        frequency = self._in_double(ctl, 0)
        register = "input_int_register_24" if self.reg_offset_int == 24 else "input_int_register_0"
        ctl.watchdog = (register, frequency) if frequency > 0 else None
        ctl.last_input_write[register] = ctl.time_s

    def _steptime(self, ctl: Controller) -> None:
        self._out_double(ctl, 0, ctl.period_s)

    def _joint_history(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, ctl.meas.q_rad)

    def _target_waypoint(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, ctl.target_tcp_pose)

    def _ik_args(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), self._in_q(ctl, 6))
        if q is None:
            raise mo.MotionError("get_inverse_kin: no solution")
        self._out_q(ctl, 0, q)

    def _ik_default(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), ctl.meas.q_rad)
        if q is None:
            raise mo.MotionError("get_inverse_kin: no solution")
        self._out_q(ctl, 0, q)

    def _ik_has_solution(self, ctl: Controller) -> None:
        seed = self._in_q(ctl, 6) if self._in_int(ctl, 0) == 61 else ctl.meas.q_rad
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), seed)
        self._out_int(ctl, 1, int(q is not None))

    def _pose_within_limits(self, ctl: Controller) -> None:
        q = ctl.kinematics.inverse(pose_to_matrix(self._in_q(ctl, 0)), ctl.meas.q_rad)
        self._out_int(ctl, 1, int(q is not None and _within_joint_limits(ctl, q)))

    def _joints_within_limits(self, ctl: Controller) -> None:
        self._out_int(ctl, 1, int(_within_joint_limits(ctl, self._in_q(ctl, 0))))

    def _joint_torques(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, np.zeros(6))

    def _pose_trans(self, ctl: Controller) -> None:
        T = pose_to_matrix(self._in_q(ctl, 0)) @ pose_to_matrix(self._in_q(ctl, 6))
        self._out_q(ctl, 0, matrix_to_pose(T))

    def _tcp_offset(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, ctl.tcp_offset)

    def _move_until_contact(self, ctl: Controller) -> None:
        xd, acc = self._in_q(ctl, 0), self._in_double(ctl, 12)
        self._stop_async_move(ctl)
        speed = mo.SpeedL(xd, acc or 0.5, ctl.kinematics, ctl.qd_max)
        self.busy = ctl.start_motion(mo.UntilContact(speed, ctl.tool_contact))

    def _tool_contact(self, ctl: Controller) -> None:
        self._out_int(ctl, 1, int(ctl.tool_contact()))

    def _jog_start(self, ctl: Controller) -> None:
        xd = self._in_q(ctl, 0)
        if round(self._in_double(ctl, 6)) == 1:  # tool feature: speeds in the TCP frame
            R = pose_to_matrix(ctl.target_tcp_pose)[:3, :3]
            xd = np.concatenate([R @ xd[:3], R @ xd[3:]])
        if isinstance(ctl.motion, mo.SpeedL):
            ctl.motion.xd_target = xd
        else:
            ctl.start_motion(
                mo.SpeedL(xd, self._in_double(ctl, 7) or 0.5, ctl.kinematics, ctl.qd_max)
            )

    def _jog_stop(self, ctl: Controller) -> None:
        self.busy = ctl.stop_motion(1.2)

    def _fk_default(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, ctl.actual_tcp_pose)

    def _fk_args(self, ctl: Controller) -> None:
        T = ctl.kinematics.flange(self._in_q(ctl, 0)) @ pose_to_matrix(self._in_q(ctl, 6))
        self._out_q(ctl, 0, matrix_to_pose(T))

    def _is_steady(self, ctl: Controller) -> None:
        self._out_int(ctl, 1, int(ctl.is_steady()))

    def _flange_pose(self, ctl: Controller) -> None:
        self._out_q(ctl, 0, matrix_to_pose(ctl.kinematics.flange(ctl.meas.q_rad)))

    def _freedrive_status(self, ctl: Controller) -> None:
        self._out_int(ctl, 1, 0)

    def _read_contact(self, ctl: Controller) -> None:
        self._out_int(ctl, 1, int(ctl.meas.contact))

    def _damping(self, ctl: Controller) -> None:
        self.force_mode_damping = self._in_double(ctl, 0)

    def _gain_scaling(self, ctl: Controller) -> None:
        self.force_mode_gain_scaling = self._in_double(ctl, 0)

    def _unsupported(self, ctl: Controller) -> None:
        ctl.add_log(
            f"rtde_control: command {self._in_int(ctl, 0)} accepted but not simulated by the twin"
        )


def _within_joint_limits(ctl: Controller, q: np.ndarray) -> bool:
    lo, hi = np.radians(ctl.spec.joint_min_deg), np.radians(ctl.spec.joint_max_deg)
    return bool(np.all(q >= lo) and np.all(q <= hi))


P = RtdeControlProgram
_HANDLERS: dict[int, Callable[[RtdeControlProgram, Controller], None]] = {
    1: P._movej, 2: P._movej_ik, 3: P._movel, 4: P._movel_fk,
    6: P._unsupported, 7: P._force_mode_stop, 8: P._zero_ft,
    9: P._speedj, 10: P._speedl, 11: P._servoj, 12: P._unsupported,
    15: P._stop_with_decel, 16: P._stop_with_decel, 17: P._set_payload,
    18: P._unsupported, 19: P._unsupported, 20: P._damping, 21: P._gain_scaling,
    24: P._servol, 25: P._tool_contact, 26: P._steptime, 27: P._joint_history,
    28: P._target_waypoint, 29: P._set_tcp, 30: P._ik_args, 31: P._protective_stop,
    33: P._stopl_stopj, 34: P._stopl_stopj, 35: P._set_watchdog,
    36: P._pose_within_limits, 37: P._joints_within_limits, 38: P._joint_torques,
    39: P._pose_trans, 40: P._tcp_offset, 41: P._jog_start, 42: P._jog_stop,
    43: P._fk_default, 44: P._fk_args, 45: P._move_path, 46: P._ik_default,
    47: P._is_steady, 51: P._move_until_contact, 52: P._unsupported, 53: P._unsupported,
    54: P._freedrive_status, 56: P._unsupported, 57: P._unsupported, 58: P._flange_pose,
    59: P._unsupported, 60: P._ik_has_solution, 61: P._ik_has_solution,
    62: P._unsupported, 63: P._unsupported, 64: P._read_contact, 65: P._set_payload,
}  # fmt: skip


# --------------------------------------------------------------------------- simple programs

_SIMPLE = {
    "movej", "movel", "stopj", "stopl", "set_standard_digital_out", "set_digital_out",
    "set_configurable_digital_out", "set_tool_digital_out", "write_output_integer_register",
    "write_output_float_register", "write_output_boolean_register", "set_tcp", "set_payload",
    "sleep", "textmsg", "popup", "protective_stop", "sync",
}  # fmt: skip


@dataclass
class SimpleProgram:
    """A straight-line program of literal statements (see the module docstring)."""

    statements: list[tuple[str, list[Any], dict[str, Any]]]
    name: str = "program"
    index: int = 0
    waiting: Any = None
    sleep_left_s: float = 0.0
    secondary: bool = False

    @classmethod
    def from_text(cls, text: str) -> SimpleProgram:
        lines = [ln for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]
        if not lines:
            raise ScriptError("empty program")
        name, secondary = "program", False
        m = re.match(r"\s*(def|sec)\s+(\w+)\s*\(\s*\)\s*:\s*$", lines[0])
        if m:
            name, secondary = m.group(2), m.group(1) == "sec"
            if lines[-1].strip() != "end":
                raise ScriptError(f"program {name!r} has no closing 'end'")
            lines = lines[1:-1]
        statements = []
        for line in lines:
            call = _parse_call(line)
            if call[0] not in _SIMPLE:
                raise ScriptError(f"unsupported statement: {line.strip()}")
            statements.append(call)
        return cls(statements, name=name, secondary=secondary)

    def kill(self, ctl: Controller) -> None:
        self.waiting = None

    def run_all_now(self, ctl: Controller) -> None:
        """Execute every statement at once (secondary programs: IO and registers only)."""
        for name, args, kwargs in self.statements:
            if name in ("movej", "movel", "stopj", "stopl", "sleep", "sync"):
                ctl.add_log(f"secondary program {self.name!r}: {name} ignored (no motion in sec)")
                continue
            self._execute(ctl, name, args, kwargs)

    def tick(self, ctl: Controller) -> bool:
        if self.waiting is not None:
            if ctl.motion is self.waiting:
                return True
            self.waiting = None
        if self.sleep_left_s > 0:
            self.sleep_left_s -= ctl.period_s
            return True
        while self.index < len(self.statements):
            name, args, kwargs = self.statements[self.index]
            self.index += 1
            try:
                self._execute(ctl, name, args, kwargs)
            except mo.MotionError as exc:
                ctl.add_log(f"program {self.name!r}: {exc}")
                return False
            if self.waiting is not None or self.sleep_left_s > 0 or name == "sync":
                return True
            if ctl.program is not self:
                return False
        return False

    def _execute(self, ctl: Controller, name: str, args: list[Any], kwargs: dict[str, Any]) -> None:
        def arg(i: int, key: str, default: Any) -> Any:
            return args[i] if len(args) > i else kwargs.get(key, default)

        if name == "movej":
            target = np.array(args[0], float)
            if kwargs.get("_pose"):
                q = ctl.kinematics.inverse(pose_to_matrix(target), ctl.target_q)
                if q is None:
                    raise mo.MotionError(
                        f"movej: no inverse kinematics solution for p{list(target)}"
                    )
                target = q
            self.waiting = ctl.start_motion(movej(ctl, target, arg(2, "v", 1.05), arg(1, "a", 1.4)))
        elif name == "movel":
            target = np.array(args[0], float)
            if not kwargs.get("_pose"):
                target = ctl.kinematics.tcp_pose(target)
            self.waiting = ctl.start_motion(movel(ctl, target, arg(2, "v", 0.25), arg(1, "a", 1.2)))
        elif name in ("stopj", "stopl"):
            self.waiting = ctl.stop_motion(float(arg(0, "a", 2.0)))
        elif name in ("set_standard_digital_out", "set_digital_out"):
            n, v = int(args[0]), bool(args[1])
            ctl.set_standard_outputs(1 << n, int(v) << n)
        elif name == "set_configurable_digital_out":
            n, v = int(args[0]), bool(args[1])
            ctl.set_configurable_outputs(1 << n, int(v) << n)
        elif name == "set_tool_digital_out":
            n, v = int(args[0]), bool(args[1])
            ctl.set_tool_outputs(1 << n, int(v) << n)
        elif name == "write_output_integer_register":
            ctl.reg.output_int[int(args[0])] = int(args[1])
        elif name == "write_output_float_register":
            ctl.reg.output_double[int(args[0])] = float(args[1])
        elif name == "write_output_boolean_register":
            bit = int(args[0])
            ctl.reg.output_bits = (
                ctl.reg.output_bits | (1 << bit) if args[1] else ctl.reg.output_bits & ~(1 << bit)
            )
        elif name == "set_tcp":
            ctl.set_tcp(np.array(args[0], float))
        elif name == "set_payload":
            ctl.payload_kg = float(args[0])
            if len(args) > 1:
                ctl.payload_cog_m = np.array(args[1], float)
        elif name == "sleep":
            self.sleep_left_s = float(args[0])
        elif name == "textmsg":
            ctl.add_log("textmsg: " + " ".join(str(a) for a in args))
        elif name == "popup":
            ctl.popup = str(args[0]) if args else ""
        elif name == "protective_stop":
            ctl.protective_stop("protective_stop() called by the program")
