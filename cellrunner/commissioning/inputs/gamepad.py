"""A gamepad (any the kernel shows as an evdev joystick: Xbox, DualShock, Logitech F310).

Hold LB to move; let go and the arm stops. In the base or tool frame (joint mode in
brackets):

=========================  ======================  ========
control                    motion                  (joint)
=========================  ======================  ========
left stick right / left    +X / -X                 J1
left stick up / down       +Y / -Y                 J2
right stick up / down      +Z / -Z                 J3
d-pad up / down            +RX / -RX               J4
d-pad right / left         +RY / -RY               J5
right stick right / left   +RZ / -RZ               J6
A                          mode: base -> tool -> joint
Y / X                      speed step up / down (10, 25, 50, 100 % of full jog speed)
=========================  ======================  ========

Stick travel inside :data:`STICK_DEAD_BAND` is zero; beyond it speed grows linearly to
full speed at full travel. A device that goes away (unplugged, ENODEV) raises
:class:`InputLost`: the session stops the arm and ends.
"""

from __future__ import annotations

import contextlib
import errno
from typing import Any

import numpy as np

from cellrunner.commissioning import jog
from cellrunner.commissioning.inputs import InputLost
from cellrunner.commissioning.servo import Command
from cellrunner.errors import PeerUnreachable, UsageError

#: fraction of a stick's travel that is no motion
STICK_DEAD_BAND = 0.12
#: evdev codes (linux/input-event-codes.h), so that the mapping reads without evdev
EV_KEY, EV_ABS = 0x01, 0x03
SYN_DROPPED = 3
ABS_X, ABS_Y, ABS_RX, ABS_RY, ABS_HAT0X, ABS_HAT0Y = 0x00, 0x01, 0x03, 0x04, 0x10, 0x11
BTN_SOUTH, BTN_NORTH, BTN_WEST, BTN_TL = 0x130, 0x133, 0x134, 0x136
HOLD, MODE, FASTER, SLOWER = BTN_TL, BTN_SOUTH, BTN_NORTH, BTN_WEST
#: axis -> (command component 0-5, sign): stick up is +, the kernel reports up as -
AXES = {
    ABS_X: (0, +1),
    ABS_Y: (1, -1),
    ABS_RY: (2, -1),
    ABS_HAT0Y: (3, -1),
    ABS_HAT0X: (4, +1),
    ABS_RX: (5, +1),
}


def find_gamepad() -> Any:
    """The first evdev device with sticks and a south button (an ``evdev.InputDevice``)."""
    try:
        import evdev
    except ImportError as exc:
        raise UsageError("--input gamepad needs evdev: pip install 'cellrunner[devices]'") from exc
    paths = evdev.list_devices()
    for path in paths:
        device = evdev.InputDevice(path)
        caps = device.capabilities()
        abs_codes = {c[0] if isinstance(c, tuple) else c for c in caps.get(EV_ABS, [])}
        if ABS_X in abs_codes and BTN_SOUTH in caps.get(EV_KEY, []):
            return device
        device.close()
    raise PeerUnreachable(f"no gamepad found among {len(paths)} input devices (/dev/input)")


class GamepadInput:
    """Reads one evdev gamepad without blocking; ``device`` may be given already open
    (anything with evdev's ``read_one``, ``absinfo``, ``path`` and ``close``)."""

    def __init__(self, path: str | None = None, mode: str = "base", device: Any = None) -> None:
        self.path, self.mode, self.device = path, mode, device
        self.name = "gamepad"
        self.speed_index = 1
        self.quit_requested = False
        self.held = False
        self.sticks = np.zeros(6)  # each component -1..1 after the dead band
        self.events = 0

    def open(self) -> None:
        if self.device is None:
            if self.path:
                import evdev

                try:
                    self.device = evdev.InputDevice(self.path)
                except OSError as exc:
                    raise PeerUnreachable(f"cannot open gamepad {self.path}: {exc}") from exc
            else:
                self.device = find_gamepad()
        self.name = f"gamepad {self.device.path}"
        self._ranges = {code: self._range(code) for code in AXES}

    def _range(self, code: int) -> tuple[float, float]:
        """(centre, half travel) of an axis; hats are -1..1."""
        try:
            info = self.device.absinfo(code)
        except (OSError, KeyError, TypeError):
            return 0.0, 1.0
        return (info.max + info.min) / 2.0, max((info.max - info.min) / 2.0, 1.0)

    def close(self) -> None:
        if self.device is not None:
            with contextlib.suppress(OSError):  # already gone
                self.device.close()

    def poll(self, now_s: float) -> Command | None:
        while True:
            try:
                event = self.device.read_one()
            except BlockingIOError:
                break
            except OSError as exc:
                self.held, self.sticks = False, np.zeros(6)
                gone = "unplugged" if exc.errno == errno.ENODEV else str(exc)
                raise InputLost(f"{self.name}: {gone}; the arm was stopped") from exc
            if event is None:
                break
            self.event(event.type, event.code, event.value)
        if not self.held:
            return None
        v = self.sticks * jog.SPEED_STEPS[self.speed_index]
        if self.mode == "joint":
            v = v * np.radians(jog.JOINT_SPEED_DEG_S)
        else:
            v = v * np.array([jog.LINEAR_SPEED_MPS] * 3 + [np.radians(jog.ANGULAR_SPEED_DEG_S)] * 3)
        return Command(self.mode, tuple(float(x) for x in v), now_s)

    def event(self, type_: int, code: int, value: int) -> None:
        """One evdev event (type, code, value)."""
        self.events += 1
        if type_ == 0 and code == SYN_DROPPED:  # the kernel dropped events: start over
            self.held, self.sticks = False, np.zeros(6)
        elif type_ == EV_KEY:
            self._button(code, value)
        elif type_ == EV_ABS and code in AXES:
            component, sign = AXES[code]
            centre, half = self._ranges.get(code, (0.0, 1.0))
            x = float(np.clip((value - centre) / half, -1.0, 1.0))
            self.sticks[component] = sign * _dead_band(x)

    def _button(self, code: int, value: int) -> None:
        pressed = value != 0
        if code == HOLD:
            self.held = pressed
        elif not pressed or value == 2:  # act on the press, not release or auto-repeat
            return
        elif code == MODE:
            self.mode = jog.MODES[(jog.MODES.index(self.mode) + 1) % len(jog.MODES)]
        elif code == FASTER:
            self.speed_index = min(self.speed_index + 1, len(jog.SPEED_STEPS) - 1)
        elif code == SLOWER:
            self.speed_index = max(self.speed_index - 1, 0)

    def header(self) -> str:
        return f"input: {self.name}  mode: {self.mode}  speed: {jog.SPEED_STEPS[self.speed_index] * 100:.0f}%"

    def status(self, now_s: float) -> str:
        sticks = ", ".join(f"{x:+.2f}" for x in self.sticks)
        return f"LB {'held' if self.held else 'released'}  sticks [{sticks}]  {self.events} events"

    def idle_reason(self, now_s: float) -> str:
        return "hold LB to move" if not self.held else "sticks centred"


def _dead_band(x: float) -> float:
    """Stick position -> speed fraction: zero inside the dead band, then linear to 1."""
    if abs(x) <= STICK_DEAD_BAND:
        return 0.0
    return float(np.sign(x) * (abs(x) - STICK_DEAD_BAND) / (1.0 - STICK_DEAD_BAND))
