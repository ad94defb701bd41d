"""Where jog and servo commands come from: one small module per input, each an
:class:`InputSource` polled once per controller period (never blocking).

``keyboard`` (terminal keys), ``gamepad`` (evdev), ``spacemouse`` (hidapi) and
``udp:[ADDR:]PORT`` (JSON datagrams from a program); :func:`open_input` builds one from
the ``--input`` text.
"""

from __future__ import annotations

from typing import Protocol

from cellrunner.commissioning.servo import Command
from cellrunner.errors import PeerUnreachable, UsageError

KINDS = ("keyboard", "gamepad", "spacemouse", "udp:PORT")


class InputLost(PeerUnreachable):
    """The input device went away (unplugged): the arm is stopped, the session ends."""


class InputSource(Protocol):
    """A source of commands. ``open`` connects, ``poll`` returns the command standing
    now (None for none), ``close`` releases it."""

    #: what the screen calls it (``gamepad /dev/input/event3``, ``udp 127.0.0.1:5005``)
    name: str
    #: the operator asked to end the session
    quit_requested: bool

    def open(self) -> None: ...

    def poll(self, now_s: float) -> Command | None:
        """Read what arrived (without blocking): the command standing at ``now_s``.
        Raises :class:`InputLost` when the device is gone."""
        ...

    def header(self) -> str:
        """The screen's first line after ``cellrunner jog``."""
        ...

    def status(self, now_s: float) -> str:
        """One screen line on the input (counters, buttons, why it sends nothing)."""
        ...

    def idle_reason(self, now_s: float) -> str:
        """Why no command stands now (``no key held``, ``no datagram for 1.2 s``)."""
        ...

    def close(self) -> None: ...


def open_input(text: str, mode: str | None = None) -> InputSource:
    """The source named by ``--input TEXT``; ``mode`` (joint, base or tool) is where a
    person's input starts: joints for the keyboard, the base frame for devices."""
    if text == "keyboard":
        from cellrunner.commissioning.inputs.keyboard import KeyboardInput

        return KeyboardInput(mode or "joint")
    frame = mode or "base"
    if text == "gamepad" or text.startswith("gamepad:"):
        from cellrunner.commissioning.inputs.gamepad import GamepadInput

        return GamepadInput(text.partition(":")[2] or None, frame)
    if text == "spacemouse" or text.startswith("spacemouse:"):
        from cellrunner.commissioning.inputs.spacemouse import SpaceMouseInput

        return SpaceMouseInput(text.partition(":")[2] or None, frame)
    if text.startswith("udp:"):
        from cellrunner.commissioning.inputs.udp import UdpInput, parse_address

        return UdpInput(*parse_address(text.removeprefix("udp:")))
    raise UsageError(f"--input {text!r}: unknown input; known: {', '.join(KINDS)}")
