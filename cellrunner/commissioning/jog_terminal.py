"""The jog session on a terminal: raw keys in, speedJ out at the controller rate through
ur_rtde, a screen showing mode, speed, TCP pose, nearest obstacle and why motion is held.

Keys: q w e r t y / a s d f g h jog joint 1-6 (or X Y Z RX RY RZ) forward / back while
held; m switches joint -> base -> tool; + and - step the speed; x, Esc or Ctrl-C quits.
"""

from __future__ import annotations

import math
import os
import select
import sys
import termios
import time
import tty
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from cellrunner.commissioning import jog
from cellrunner.errors import PeerUnreachable
from cellrunner.model.geometry import rpy_deg_of

if TYPE_CHECKING:
    from cellrunner.planning.world import CellWorld

#: screen refresh and governor check period (s); the stream itself runs every period
SCREEN_S = 0.1
GOVERN_S = 0.02
#: a session ends by itself after this long (s)
MAX_SESSION_S = 4 * 3600.0


class JogSession:
    """Construct, :meth:`connect`, :meth:`run` (until Esc), :meth:`close`."""

    def __init__(
        self, world: CellWorld, host: str, mode: str = "joint", out: TextIO | None = None
    ) -> None:
        self.world, self.host, self.mode = world, host, mode
        self.kinematics = world.kinematics
        self.governor = jog.Governor(self.kinematics, world.collision)
        self.speed_index = 1
        self.out = out if out is not None else sys.stdout
        # ur_rtde's RTDEControlInterface and RTDEReceiveInterface (untyped bindings)
        self._control: Any = None
        self._receive: Any = None
        self.status = "stopped"

    def connect(self) -> None:
        from cellrunner.backends.ur_probe import controller_version

        controller_version(self.host, 3.0)
        import rtde_control
        import rtde_receive

        try:
            rate = self.world.spec.rate_hz
            self._receive = rtde_receive.RTDEReceiveInterface(
                self.host, rate, ["timestamp", "actual_q", "actual_qd", "safety_mode"]
            )
            self._control = rtde_control.RTDEControlInterface(self.host, rate)
        except (RuntimeError, OSError) as exc:
            raise PeerUnreachable(f"cannot jog the arm at {self.host}: {exc}") from exc

    def close(self) -> None:
        if self._control is not None:
            try:
                self._control.speedStop(jog.JOG_ACCEL_RAD_S2 * 2)
                self._control.stopScript()
            finally:
                self._control.disconnect()
        if self._receive is not None:
            self._receive.disconnect()

    def run(self) -> None:
        fd = sys.stdin.fileno()
        saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        try:
            self._loop(fd)
        finally:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)

    def _loop(self, fd: int) -> None:
        deadman = jog.DeadMan()
        period_s = 1.0 / self.world.spec.rate_hz
        verdict, qd_cmd = None, np.zeros(6)
        next_screen = next_govern = 0.0
        t_end = time.monotonic() + MAX_SESSION_S
        while time.monotonic() < t_end:
            t_start = self._control.initPeriod()
            now = time.monotonic()
            if select.select([fd], [], [], 0)[0]:
                for key in os.read(fd, 64).decode(errors="ignore"):
                    if key in ("\x1b", "x"):
                        return
                    if self._key(key, now):
                        deadman.press(key, now)
            q = np.array(self._receive.getActualQ())
            held = deadman.held(now)
            if held is None:
                qd_cmd, verdict, self.status = np.zeros(6), None, "stopped (no key held)"
            elif now >= next_govern or verdict is None:
                axis, sign = jog.KEYS[held]
                request = jog.requested_qd(
                    self.kinematics, q, self.mode, axis, sign, jog.SPEED_STEPS[self.speed_index]
                )
                verdict = self.governor.judge(q, request)
                qd_cmd = request * verdict.scale
                label = self._axis_label(axis, sign)
                self.status = (
                    f"moving {label}"
                    if verdict.scale >= 1
                    else f"slowing ({verdict.scale * 100:.0f}%): {verdict.reason}"
                    if verdict.scale > 0
                    else f"stopped: {verdict.reason}"
                )
                next_govern = now + GOVERN_S
            self._control.speedJ(list(qd_cmd), jog.JOG_ACCEL_RAD_S2, period_s)
            if now >= next_screen:
                self._draw(q, verdict)
                next_screen = now + SCREEN_S
            self._control.waitPeriod(t_start)

    def _key(self, key: str, now: float) -> bool:
        """Handle a command key; True for a jog key."""
        if key in jog.KEYS:
            return True
        if key == "m":
            self.mode = jog.MODES[(jog.MODES.index(self.mode) + 1) % len(jog.MODES)]
        elif key == "+":
            self.speed_index = min(self.speed_index + 1, len(jog.SPEED_STEPS) - 1)
        elif key == "-":
            self.speed_index = max(self.speed_index - 1, 0)
        return False

    def _axis_label(self, axis: int, sign: int) -> str:
        name = f"J{axis + 1}" if self.mode == "joint" else ("X", "Y", "Z", "RX", "RY", "RZ")[axis]
        return f"{'+' if sign > 0 else '-'}{name}"

    def _draw(self, q: np.ndarray, verdict: jog.Verdict | None) -> None:
        T = self.kinematics.T_world_tcp(q)
        if verdict is None:
            verdict = self.governor.judge(q, np.zeros(6))
        xyz = ", ".join(f"{v:.4f}" for v in T[:3, 3])
        rpy = ", ".join(f"{v:.2f}" for v in rpy_deg_of(T[:3, :3]))
        lines = [
            f"cellrunner jog  mode: {self.mode}  speed: {jog.SPEED_STEPS[self.speed_index] * 100:.0f}%",
            "keys: q w e r t y +  a s d f g h -  (joint 1-6 / X Y Z RX RY RZ)  m mode  +/- speed  x or Esc quit",
            f"TCP (world): xyz [{xyz}] m  rpy [{rpy}] deg",
            f"joints: [{', '.join(f'{math.degrees(v):.2f}' for v in q)}] deg",
            f"nearest obstacle: {verdict.nearest} {verdict.clearance_m * 1000:.0f} mm beyond its clearance",
            f"singularity distance: {verdict.singularity}",
            f"status: {self.status}",
        ]
        self.out.write("\x1b[H\x1b[2J" + "\r\n".join(lines) + "\r\n")
        self.out.flush()
