"""Simple programs: a ``def``/``sec`` block or one line of literal statements.

What ``sendCustomScriptFunction`` and hand-written one-liners usually hold (see
:mod:`cellrunner.twin.script`); run statement by statement, one controller period at a time.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin.controller import Controller
from cellrunner.twin.kinematics import pose_to_matrix
from cellrunner.twin.moves import movej, movel
from cellrunner.twin.script_text import ScriptError, parse_call

_SIMPLE = {
    "movej", "movel", "stopj", "stopl", "set_standard_digital_out", "set_digital_out",
    "set_configurable_digital_out", "set_tool_digital_out", "write_output_integer_register",
    "write_output_float_register", "write_output_boolean_register", "set_tcp", "set_payload",
    "sleep", "textmsg", "popup", "protective_stop", "sync", "encoder_enable_pulse_decode",
    "encoder_set_tick_count",
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
            call = parse_call(line)
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
            try:
                self._execute(ctl, name, args, kwargs)
            except mo.MotionError as exc:  # the program fails, as a controller's does
                ctl.add_log(f"secondary program {self.name!r}: {exc}")
                return

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
        elif name == "encoder_enable_pulse_decode":
            try:
                ctl.pulse_decoders.enable(*(int(a) for a in args[:4]))
            except (ValueError, TypeError) as exc:
                raise mo.MotionError(f"encoder_enable_pulse_decode: {exc}") from exc
        elif name == "encoder_set_tick_count":
            try:
                ctl.pulse_decoders.set_tick_count(int(args[0]), int(args[1]))
            except (ValueError, TypeError, IndexError) as exc:
                raise mo.MotionError(f"encoder_set_tick_count: {exc}") from exc
        elif name == "protective_stop":
            ctl.protective_stop("protective_stop() called by the program")
