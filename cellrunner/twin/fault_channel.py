"""The twin's fault channel (TCP 29990, not a UR port): faults a test or an engineer injects.

One command per line, one reply line, ``ok ...`` or ``error ...``; :data:`FAULT_COMMANDS`
lists them. :class:`~cellrunner.twin.server.TwinServer` answers the ones about its
connections and timing; :func:`controller_command` the ones about the controller, under its
lock. :class:`FaultClient` is the other end.

A command it cannot run raises ``ValueError``: the channel's one refusal, which the server
answers as ``error TEXT`` and :class:`FaultClient` raises again for the line it sent (a
test's tool, never reached by a cell's user).
"""

from __future__ import annotations

import json
import re
import socket
from typing import Any

from cellrunner.twin.controller import Controller, RobotMode, RuntimeState, SafetyMode
from cellrunner.twin.conveyor_channel import CONVEYOR_COMMANDS, conveyor_command

FAULT_PORT = 29990

FAULT_COMMANDS = """\
ping                          -> ok pong
state                         -> ok {json: modes, q, outputs, inputs, programs, time}
log [N]                       -> ok [json list of the last N controller log lines]
timing                        -> ok {json: real-time loop period stats over the last ~4000 periods}
protective_stop [REASON]      -> the controller raises a protective stop now
collision [on|off]            -> the physics reports contact (protective stop follows)
estop press [system]|release  -> robot (or system) emergency stop pressed / released
fault                         -> safety fault (needs restart safety)
grip_miss | part_slip         -> the physics moves the next part away / drops the held part in the air
input CH 0|1|clear            -> force digital input CH (DI0-7, CI0-7, TI0-1)
wrench FX FY FZ TX TY TZ      -> flange wrench the physics reports (N, N m)
remote on|off                 -> remote / local control
disconnect                    -> close every client connection now
blackout SECONDS              -> close every client and refuse connections for SECONDS
record on|off                 -> start (afresh) / stop recording the servo set-points received
record save PATH              -> write them to PATH (.npy: rows of time_s, q1..q6 rad); -> ok N
parts                         -> ok {json: part name -> [x, y, z] world m} (a cell's twin)
belt NAME speed MPS [RAMP] | jump M | travel -> runs at MPS (ramp m/s^2) / encoder jumps M m / ok travel m
"""


def parse_channel(name: str) -> int:
    """Bit of a digital channel name: DI0-7 -> 0-7, CI0-7 -> 8-15, TI0-1 -> 16-17
    (DO/CO/TO likewise for outputs)."""
    m = re.fullmatch(r"([DCT])[IO](\d+)", name.strip().upper())
    if not m:
        raise ValueError(f"unknown channel {name!r}; expected DI0-7, CI0-7, TI0-1")
    base, index = {"D": 0, "C": 8, "T": 16}[m.group(1)], int(m.group(2))
    if index >= (2 if m.group(1) == "T" else 8):
        raise ValueError(f"channel {name!r} out of range")
    return base + index


def controller_command(ctl: Controller, cmd: str, args: list[str]) -> str | None:
    """Execute one controller command of the fault channel (call under ``ctl.lock``);
    its reply text, or None when ``cmd`` is not one of them."""
    if cmd in CONVEYOR_COMMANDS:
        return conveyor_command(ctl.physics, cmd, args)
    if cmd == "log":
        n = int(args[0]) if args else 50
        return json.dumps(list(ctl.log)[-n:])
    if cmd == "protective_stop":
        ctl.protective_stop(" ".join(args) or "requested on the fault channel")
        return "protective_stop"
    if cmd == "collision":
        active = not args or args[0].lower() != "off"
        inject = getattr(ctl.physics, "inject_contact", None)
        if inject is not None:
            inject(active)
        elif active:
            ctl.protective_stop("collision detected")
        return f"collision {'on' if active else 'off'}"
    if cmd == "estop":
        if args and args[0].lower() == "release":
            ctl.release_estop()
            return "estop released"
        system = len(args) > 1 and args[1].lower() == "system"
        ctl.press_estop(system=system)
        return f"{'system ' if system else ''}estop pressed"
    if cmd == "fault":
        ctl.raise_fault()
        return "fault"
    if cmd in ("grip_miss", "part_slip"):
        inject = getattr(ctl.physics, "inject_fault", None)
        if inject is None:
            raise ValueError("this physics has no parts to miss or drop")
        inject(cmd)
        return cmd
    if cmd == "input":
        bit = parse_channel(args[0])
        if args[1].lower() == "clear":
            ctl.input_overrides.pop(bit, None)
        else:
            ctl.input_overrides[bit] = args[1] not in ("0", "false", "False")
        return f"input {args[0]} {args[1]}"
    if cmd == "wrench":
        values = [float(x) for x in args]
        if len(values) != 6:
            raise ValueError("wrench needs 6 numbers: FX FY FZ TX TY TZ")
        setter = getattr(ctl.physics, "set_wrench", None)
        if setter is None:
            raise ValueError("this physics has no settable wrench")
        setter(values)
        return "wrench"
    if cmd == "record":
        return record(ctl, args)
    if cmd == "remote":
        ctl.remote_control = args[0].lower() == "on"
        return f"remote {args[0].lower()}"
    return None


def record(ctl: Controller, args: list[str]) -> str:
    """The servo set-points as received (for tests that compare them with a plan)."""
    if args[:1] == ["on"]:
        ctl.servo_record = []
        return "record on"
    if args[:1] == ["off"]:
        ctl.servo_record = None
        return "record off"
    if args[:1] == ["save"] and len(args) == 2:
        import numpy as np

        rows = list(ctl.servo_record or [])
        np.save(args[1], np.array(rows, dtype=float).reshape(len(rows), 7))
        return str(len(rows))
    raise ValueError("record on | record off | record save PATH")


def loop_timing(periods_s: list[float], nominal_s: float) -> dict[str, float]:
    """Statistics of a real-time loop's periods (s) and their deviation from ``nominal_s``."""
    periods = sorted(periods_s)
    if not periods:
        return {}
    deviation = sorted(abs(p - nominal_s) for p in periods)

    def pct(values: list[float], q: float) -> float:
        return values[min(len(values) - 1, int(q * len(values)))]

    return {
        "n": len(periods),
        "period_s": nominal_s,
        "period_p50_s": pct(periods, 0.5),
        "period_max_s": periods[-1],
        "jitter_p50_s": pct(deviation, 0.5),
        "jitter_p99_s": pct(deviation, 0.99),
        "jitter_max_s": deviation[-1],
    }


def controller_state(ctl: Controller) -> dict[str, Any]:
    """A JSON-able snapshot of the controller (call under ``ctl.lock``)."""
    return {
        "time_s": ctl.time_s,
        "robot_mode": RobotMode(ctl.robot_mode).name,
        "safety_mode": SafetyMode(ctl.safety_mode).name,
        "runtime_state": RuntimeState(ctl.runtime_state).name,
        "program": ctl.program.name if ctl.program is not None else None,
        "programs_started": ctl.programs_started,
        "estop_pressed": ctl.estop_pressed,
        "remote_control": ctl.remote_control,
        "q_rad": [float(x) for x in ctl.meas.q_rad],
        "target_q_rad": [float(x) for x in ctl.target_q],
        "tcp_pose": [float(x) for x in ctl.actual_tcp_pose],
        "digital_outputs": ctl.digital_output_bits,
        "digital_inputs": ctl.digital_input_bits,
        "payload_kg": ctl.payload_kg,
        "tcp_offset": [float(x) for x in ctl.tcp_offset],
        "watchdog": list(ctl.watchdog) if ctl.watchdog else None,
    }


class FaultClient:
    """Client of a twin's fault channel (e.g. for ``--inject`` against ``cellrunner twin``).

    ``FaultClient("127.0.0.2").command("protective_stop")`` -> reply text after ``ok``;
    a refused command raises ValueError, an unreachable twin OSError."""

    def __init__(self, host: str, port: int = FAULT_PORT, timeout_s: float = 3.0) -> None:
        self.host, self.port, self.timeout_s = host, port, timeout_s

    def command(self, line: str) -> str:
        with socket.create_connection((self.host, self.port), timeout=self.timeout_s) as sock:
            sock.sendall((line.strip() + "\n").encode())
            reply = b""
            while not reply.endswith(b"\n"):
                chunk = sock.recv(65536)
                if not chunk:
                    break
                reply += chunk
        text = reply.decode().strip()
        if not text.startswith("ok"):
            raise ValueError(f"twin fault channel refused {line!r}: {text}")
        return text[3:]

    def state(self) -> dict[str, Any]:
        state: dict[str, Any] = json.loads(self.command("state"))
        return state
