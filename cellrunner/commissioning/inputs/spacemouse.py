"""A 3Dconnexion SpaceMouse (SpaceNavigator, SpaceMouse Compact, Wireless, Pro) read as a
HID device through hidapi: six axes move the TCP at once, in the base or the tool frame.

The device's axes (x right, y toward you, z down; rotations about them) are turned into a
right-handed frame: push the cap away = +Y, right = +X, lift = +Z, tilt it away = +RX
(about X), roll it right = +RY, twist it counter-clockwise = +RZ. Deflection inside
:data:`DEAD_BAND` of :data:`FULL_SCALE` is zero; beyond it speed grows linearly to full
jog speed. The left button switches base <-> tool; the right one steps the speed
(10, 25, 50, 100 %). A device that goes away (a read error) raises :class:`InputLost`.

HID reports: id 1 carries x, y, z (int16, little-endian; newer devices add rx, ry, rz in
the same report), id 2 rx, ry, rz, id 3 the buttons (bit 0 left, bit 1 right).
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from cellrunner.commissioning import jog
from cellrunner.commissioning.inputs import InputLost
from cellrunner.commissioning.servo import Command
from cellrunner.errors import PeerUnreachable, UsageError

#: a full deflection, in device counts
FULL_SCALE = 350.0
#: fraction of a full deflection that is no motion
DEAD_BAND = 0.08
#: the device's (x, y, z, rx, ry, rz) -> right-handed, as the module docstring says
SIGNS = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
#: 3Dconnexion devices: (vendor id, product ids; empty: every product of the vendor)
DEVICES = (
    (
        0x046D,
        (
            0xC603,
            0xC605,
            0xC606,
            0xC621,
            0xC623,
            0xC625,
            0xC626,
            0xC627,
            0xC628,
            0xC629,
            0xC62B,
            0xC62E,
            0xC62F,
            0xC631,
            0xC632,
            0xC633,
            0xC635,
            0xC652,
        ),
    ),
    (0x256F, ()),
)
READ_SIZE = 64


def find_spacemouse() -> dict[str, Any]:
    """hidapi's description of the first SpaceMouse plugged in."""
    hid = _hid()
    for info in hid.enumerate():
        for vendor, products in DEVICES:
            if info["vendor_id"] == vendor and (not products or info["product_id"] in products):
                return dict(info)
    raise PeerUnreachable("no SpaceMouse found among the HID devices")


def _hid() -> Any:
    try:
        import hid
    except ImportError as exc:
        raise UsageError(
            "--input spacemouse needs hidapi: pip install 'cellrunner[devices]'"
        ) from exc
    return hid


class SpaceMouseInput:
    """Reads one SpaceMouse without blocking; ``device`` may be given already open
    (anything with hidapi's ``read(size)`` returning a list of bytes and ``close``)."""

    def __init__(self, path: str | None = None, mode: str = "base", device: Any = None) -> None:
        self.path, self.device = path, device
        self.mode = mode if mode in ("base", "tool") else "base"
        self.name = "spacemouse"
        self.speed_index = 1
        self.quit_requested = False
        self.axes = np.zeros(6)  # device counts, in the device's own axes
        self.buttons = 0
        self.reports = 0

    def open(self) -> None:
        if self.device is None:
            hid = _hid()
            path = self.path.encode() if self.path else find_spacemouse()["path"]
            device = hid.device()
            try:
                device.open_path(path)
            except OSError as exc:
                raise PeerUnreachable(f"cannot open SpaceMouse {path!r}: {exc}") from exc
            device.set_nonblocking(1)
            self.device = device
            self.name = (
                f"spacemouse {path.decode(errors='replace') if isinstance(path, bytes) else path}"
            )

    def close(self) -> None:
        if self.device is not None:
            self.device.close()

    def poll(self, now_s: float) -> Command | None:
        for _ in range(64):
            try:
                data = self.device.read(READ_SIZE)
            except (OSError, ValueError) as exc:
                self.axes = np.zeros(6)
                raise InputLost(f"{self.name}: unplugged ({exc}); the arm was stopped") from exc
            if not data:
                break
            self.report(bytes(data))
        v = self.fractions() * jog.SPEED_STEPS[self.speed_index]
        if not np.any(v):
            return None
        v = v * np.array([jog.LINEAR_SPEED_MPS] * 3 + [np.radians(jog.ANGULAR_SPEED_DEG_S)] * 3)
        return Command(self.mode, tuple(float(x) for x in v), now_s)

    def report(self, data: bytes) -> None:
        """One HID report (its first byte the report id)."""
        self.reports += 1
        if data[0] == 1 and len(data) >= 13:
            self.axes[:] = struct.unpack("<6h", data[1:13])
        elif data[0] == 1 and len(data) >= 7:
            self.axes[:3] = struct.unpack("<3h", data[1:7])
        elif data[0] == 2 and len(data) >= 7:
            self.axes[3:] = struct.unpack("<3h", data[1:7])
        elif data[0] == 3 and len(data) >= 2:
            pressed = data[1] & ~self.buttons
            self.buttons = data[1]
            if pressed & 1:
                self.mode = "tool" if self.mode == "base" else "base"
            if pressed & 2:
                self.speed_index = (self.speed_index + 1) % len(jog.SPEED_STEPS)

    def fractions(self) -> np.ndarray:
        """Deflection per axis, right-handed, -1..1 after the dead band."""
        x = np.clip(self.axes / FULL_SCALE, -1.0, 1.0)
        out = np.where(
            np.abs(x) <= DEAD_BAND, 0.0, np.sign(x) * (np.abs(x) - DEAD_BAND) / (1 - DEAD_BAND)
        )
        return np.asarray(out * SIGNS, float)

    def header(self) -> str:
        return f"input: {self.name}  frame: {self.mode}  speed: {jog.SPEED_STEPS[self.speed_index] * 100:.0f}%"

    def status(self, now_s: float) -> str:
        axes = ", ".join(f"{x:+.0f}" for x in self.axes)
        return f"axes [{axes}] counts  buttons {self.buttons:#04x}  {self.reports} reports"

    def idle_reason(self, now_s: float) -> str:
        return "cap at rest"
