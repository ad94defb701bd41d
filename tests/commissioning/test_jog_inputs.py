"""The jog's inputs on their own: UDP datagrams from a real socket, a gamepad through a
virtual kernel device (evdev UInput, where /dev/uinput exists) and through recorded
evdev events, a SpaceMouse through recorded HID reports; unplugging ends the input."""

from __future__ import annotations

import errno
import json
import math
import os
import socket
import time

import numpy as np
import pytest

from cellrunner.commissioning import jog
from cellrunner.commissioning.inputs import InputLost, open_input
from cellrunner.commissioning.inputs import gamepad as gp
from cellrunner.commissioning.inputs.spacemouse import SpaceMouseInput
from cellrunner.commissioning.inputs.udp import Malformed, UdpInput, parse_datagram
from cellrunner.errors import UsageError


# ------------------------------------------------------------------ UDP
@pytest.mark.parametrize(
    ("data", "why"),
    [
        (b"\xff\xfe", "not JSON"),
        (b"[1]", "not a JSON object"),
        (b'{"twist": [0, 0, 0, 0, 0, 0]}', "seq must be an integer"),
        (b'{"seq": 1.5, "twist": [0, 0, 0, 0, 0, 0]}', "seq must be an integer"),
        (b'{"seq": 1, "twist": [0, 0, 0, 0, 0]}', "twist must be a list of 6 numbers"),
        (b'{"seq": 1, "twist": [0, 0, 0, 0, 0, "1"]}', "twist must be a list of 6 numbers"),
        (
            b'{"seq": 1, "joints": [0, 0, 0, 0, 0, Infinity]}',
            "joints has a value that is not finite",
        ),
        (
            b'{"seq": 1, "twist": [0, 0, 0, 0, 0, 0], "joints": [0, 0, 0, 0, 0, 0]}',
            "give one of twist or joints",
        ),
        (
            b'{"seq": 1, "frame": "flange", "twist": [0, 0, 0, 0, 0, 0]}',
            "frame 'flange': known base, tool",
        ),
        (b'{"seq": 1, "twist": [0, 0, 0, 0, 0, 0], "speed": 2}', "unknown keys ['speed']"),
    ],
)
def test_malformed_datagrams_say_why(data, why):
    with pytest.raises(Malformed, match=None) as info:
        parse_datagram(data)
    assert str(info.value).startswith(why)


def test_datagrams_in_si_units():
    d = parse_datagram(b'{"seq": 7, "frame": "tool", "twist": [0.01, 0, 0, 0, 0, 90]}')
    assert (d.seq, d.frame, d.velocity[0]) == (7, "tool", 0.01)
    assert d.velocity[5] == pytest.approx(math.pi / 2)
    j = parse_datagram(b'{"seq": 8, "joints": [10, 0, 0, 0, 0, 0]}')
    assert j.frame == "joint" and j.velocity[0] == pytest.approx(math.radians(10))


def test_udp_on_a_real_socket_newest_seq_stands_and_bad_ones_are_counted():
    from tests.rig import free_port

    port = free_port("127.0.0.1")
    source = open_input(f"udp:{port}")
    assert isinstance(source, UdpInput) and source.host == "127.0.0.1"
    source.open()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for seq, vx in ((5, 0.05), (3, -0.05), (6, 0.02)):
                tx.sendto(
                    json.dumps({"seq": seq, "twist": [vx, 0, 0, 0, 0, 0]}).encode(),
                    ("127.0.0.1", port),
                )
            tx.sendto(b"{oops", ("127.0.0.1", port))
            time.sleep(0.05)
            now = time.monotonic()
            command = source.poll(now)
            assert command is not None and command.velocity[0] == 0.02
            assert (source.received, source.malformed, source.stale) == (4, 1, 1)
            # a sender that restarted (seq from 1 again) is heard after a silence
            tx.sendto(
                json.dumps({"seq": 1, "twist": [0.01, 0, 0, 0, 0, 0]}).encode(), ("127.0.0.1", port)
            )
            time.sleep(0.05)
            assert source.poll(now + 0.01).velocity[0] == 0.02, "too soon: stale"
            tx.sendto(
                json.dumps({"seq": 1, "twist": [0.01, 0, 0, 0, 0, 0]}).encode(), ("127.0.0.1", port)
            )
            time.sleep(0.05)
            assert source.poll(now + 2.0).velocity[0] == 0.01
    finally:
        source.close()


def test_bad_input_texts_are_usage_errors():
    with pytest.raises(
        UsageError, match="unknown input; known: keyboard, gamepad, spacemouse, udp:PORT"
    ):
        open_input("joystick")
    with pytest.raises(UsageError, match="write udp:PORT or udp:ADDR:PORT"):
        open_input("udp:http")
    assert open_input("udp:127.0.0.5:6000").name == "udp 127.0.0.5:6000"


# ------------------------------------------------------------------ gamepad
class Recorded:
    """A gamepad replayed from events recorded with evdev (type, code, value); after the
    last one it reads as unplugged (ENODEV), as evdev does."""

    path = "/dev/input/event-recorded"

    def __init__(self, events, unplug=True):
        import evdev

        self.events = [evdev.InputEvent(0, 0, *e) for e in events]
        self.unplug = unplug
        self.absinfo_ = evdev.AbsInfo(0, -32768, 32767, 16, 128, 0)

    def read_one(self):
        if self.events:
            return self.events.pop(0)
        if self.unplug:
            raise OSError(errno.ENODEV, "No such device")
        return None

    def absinfo(self, code):
        if code in (gp.ABS_HAT0X, gp.ABS_HAT0Y):
            import evdev

            return evdev.AbsInfo(0, -1, 1, 0, 0, 0)
        return self.absinfo_

    def close(self):
        pass


# an Xbox pad: left stick pushed right 3/4, LB held, A pressed (mode), d-pad up
PUSH_RIGHT = [(3, gp.ABS_X, 24575), (0, 0, 0), (1, gp.BTN_TL, 1), (0, 0, 0)]


def test_a_recorded_gamepad_moves_only_while_lb_is_held_then_unplugs():
    pad = gp.GamepadInput(mode="base", device=Recorded(PUSH_RIGHT[:1], unplug=False))
    pad.open()
    assert pad.poll(0.0) is None, "stick pushed but LB not held"
    pad.event(1, gp.BTN_TL, 1)
    command = pad.poll(0.01)
    expected = (0.75 - gp.STICK_DEAD_BAND) / (1 - gp.STICK_DEAD_BAND)
    assert command.frame == "base"
    assert command.velocity[0] == pytest.approx(expected * 0.25 * jog.LINEAR_SPEED_MPS, rel=1e-3)
    assert not any(command.velocity[1:])
    pad.event(1, gp.BTN_TL, 0)
    assert pad.poll(0.02) is None, "LB released: stop"

    pad = gp.GamepadInput(
        mode="base",
        device=Recorded(
            PUSH_RIGHT + [(3, gp.ABS_HAT0Y, -1), (1, gp.BTN_SOUTH, 1), (1, gp.BTN_SOUTH, 0)]
        ),
    )
    pad.open()
    with pytest.raises(InputLost, match="unplugged; the arm was stopped"):
        pad.poll(0.0)
    assert pad.mode == "tool" and not pad.held
    assert pad.sticks[0] == 0 and pad.sticks[3] == 0


def test_a_stick_inside_the_dead_band_is_still():
    pad = gp.GamepadInput(
        device=Recorded(
            [(1, gp.BTN_TL, 1), (3, gp.ABS_Y, -3000), (3, gp.ABS_RY, 100)], unplug=False
        )
    )
    pad.open()
    command = pad.poll(0.0)
    assert command is not None and not any(command.velocity)


@pytest.mark.skipif(
    not os.access("/dev/uinput", os.W_OK),
    reason="no /dev/uinput here: the recorded-events tests above cover the gamepad",
)
def test_a_virtual_gamepad_the_kernel_sees():
    import evdev
    from evdev import ecodes as e

    caps = {
        e.EV_KEY: [e.BTN_SOUTH, e.BTN_NORTH, e.BTN_WEST, e.BTN_TL],
        e.EV_ABS: [
            (code, evdev.AbsInfo(0, -32768, 32767, 16, 128, 0))
            for code in (e.ABS_X, e.ABS_Y, e.ABS_RX, e.ABS_RY)
        ],
    }
    with evdev.UInput(caps, name="cellrunner test pad") as ui:
        time.sleep(0.3)
        pad = gp.GamepadInput(ui.device.path)
        pad.open()
        ui.write(e.EV_ABS, e.ABS_RY, -32768)  # right stick fully up: +Z
        ui.write(e.EV_KEY, e.BTN_TL, 1)
        ui.syn()
        time.sleep(0.05)
        command = pad.poll(time.monotonic())
        assert command is not None and command.velocity[2] == pytest.approx(
            0.25 * jog.LINEAR_SPEED_MPS, rel=1e-3
        )
    with pytest.raises(InputLost):
        for _ in range(50):
            pad.poll(time.monotonic())
            time.sleep(0.01)


# ------------------------------------------------------------------ SpaceMouse
class RecordedHid:
    """HID reports recorded from a SpaceMouse (report id first); then a read error."""

    def __init__(self, reports):
        self.reports = [list(r) for r in reports]

    def read(self, size):
        if self.reports:
            return self.reports.pop(0)
        raise OSError("read error")

    def close(self):
        pass


def report(report_id, *values):
    import struct

    return bytes([report_id]) + struct.pack(f"<{len(values)}h", *values)


def test_a_recorded_spacemouse_moves_six_axes_then_unplugs():
    # one period reads the two axis reports, then nothing is pending ([]); the next, an error
    reports = [report(1, 0, -350, 0), report(2, 0, 0, 175), b""]
    mouse = SpaceMouseInput(mode="tool", device=RecordedHid(reports))
    command = mouse.poll(0.0)
    assert command.frame == "tool"
    v = np.array(command.velocity)
    assert v[1] == pytest.approx(0.25 * jog.LINEAR_SPEED_MPS), "cap pushed away: +Y"
    frac = (0.5 - 0.08) / (1 - 0.08)
    assert v[5] == pytest.approx(-frac * 0.25 * math.radians(jog.ANGULAR_SPEED_DEG_S))
    assert v[0] == v[2] == v[3] == v[4] == 0
    with pytest.raises(InputLost, match="unplugged"):
        mouse.poll(0.01)


def test_spacemouse_buttons_and_the_newer_single_report():
    mouse = SpaceMouseInput(
        device=RecordedHid([report(3, 1), report(3, 0), report(1, 20, 0, 0, 0, 0, -350)])
    )
    mouse.device.reports.append([])
    command = mouse.poll(0.0)
    assert mouse.mode == "tool", "left button: base -> tool"
    assert command.velocity[0] == 0, "20 counts is inside the dead band"
    assert command.velocity[5] == pytest.approx(0.25 * math.radians(jog.ANGULAR_SPEED_DEG_S))
