"""Keys held on a terminal: q w e r t y / a s d f g h jog joint 1-6 (or X Y Z RX RY RZ)
forward / back while held; m switches joint -> base -> tool; + and - step the speed;
x or Esc quits. A held key is its auto-repeat (see :class:`jog.DeadMan`)."""

from __future__ import annotations

import os
import select
import sys
import termios
import tty
from typing import Any

from cellrunner.commissioning import jog
from cellrunner.commissioning.servo import Command
from cellrunner.errors import UsageError


class KeyboardInput:
    """Reads raw keys from the terminal on stdin."""

    name = "keyboard"

    def __init__(self, mode: str = "joint") -> None:
        self.mode = mode
        self.speed_index = 1
        self.quit_requested = False
        self.deadman = jog.DeadMan()
        self._fd = -1
        self._saved: list[Any] | None = None

    def open(self) -> None:
        if not sys.stdin.isatty():
            raise UsageError(
                "jog needs a terminal for --input keyboard: keys are read as they are held "
                "(--input gamepad, spacemouse or udp:PORT jog without one)"
            )
        self._fd = sys.stdin.fileno()
        self._saved = termios.tcgetattr(self._fd)
        tty.setcbreak(self._fd)

    def close(self) -> None:
        if self._saved is not None:
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
            self._saved = None

    @property
    def speed(self) -> float:
        return jog.SPEED_STEPS[self.speed_index]

    def poll(self, now_s: float) -> Command | None:
        if select.select([self._fd], [], [], 0)[0]:
            for key in os.read(self._fd, 64).decode(errors="ignore"):
                self.key(key, now_s)
        held = self.deadman.held(now_s)
        if held is None:
            return None
        axis, sign = jog.KEYS[held]
        v = jog.axis_velocity(self.mode, axis, sign, self.speed)
        return Command(self.mode, tuple(float(x) for x in v), now_s)

    def key(self, key: str, now_s: float) -> None:
        """Handle one key pressed at ``now_s``."""
        if key in ("\x1b", "x"):
            self.quit_requested = True
        elif key in jog.KEYS:
            self.deadman.press(key, now_s)
        elif key == "m":
            self.mode = jog.MODES[(jog.MODES.index(self.mode) + 1) % len(jog.MODES)]
        elif key == "+":
            self.speed_index = min(self.speed_index + 1, len(jog.SPEED_STEPS) - 1)
        elif key == "-":
            self.speed_index = max(self.speed_index - 1, 0)

    def header(self) -> str:
        return f"mode: {self.mode}  speed: {self.speed * 100:.0f}%"

    def status(self, now_s: float) -> str:
        return (
            "keys: q w e r t y +  a s d f g h -  (joint 1-6 / X Y Z RX RY RZ)  m mode  "
            "+/- speed  x or Esc quit"
        )

    def idle_reason(self, now_s: float) -> str:
        return "no key held"

    def label(self, command: Command) -> str:
        """``+X``, ``-J3``: the key's axis."""
        held = self.deadman.key
        if held is None:
            return "stopped"
        axis, sign = jog.KEYS[held]
        name = f"J{axis + 1}" if self.mode == "joint" else ("X", "Y", "Z", "RX", "RY", "RZ")[axis]
        return f"moving {'+' if sign > 0 else '-'}{name}"
