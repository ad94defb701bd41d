"""Dashboard server (port 29999) commands and their replies, as a PolyScope 5 / CB3 gives them.

One command per line, case-insensitive; one reply line each. The greeting on connect is
:data:`GREETING`. Commands that act on the robot are refused with
:data:`NOT_IN_REMOTE` while the controller is in local control.
"""

from __future__ import annotations

from collections.abc import Callable

from cellrunner.twin.controller import Controller, RobotMode, RuntimeState, SafetyMode

GREETING = "Connected: Universal Robots Dashboard Server"
NOT_IN_REMOTE = (
    "Command is not allowed due to safety reasons, please switch robot to Remote Control mode "
    "and reconnect to port 29999"
)
_REMOTE_ONLY = (
    "power on", "power off", "brake release", "unlock protective stop", "restart safety",
    "play", "stop", "pause", "load ", "shutdown",
)  # fmt: skip


class InstalledProgram:
    """A ``.urp`` loaded on the pendant: the twin cannot read it, so playing it runs
    nothing but shows PLAYING until ``stop`` (what a PLC sequence watches)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def tick(self, ctl: Controller) -> bool:
        return True

    def kill(self, ctl: Controller) -> None:
        pass


def software_version(ctl: Controller) -> str:
    major, minor, bugfix, build = ctl.versions
    return f"{major}.{minor}.{bugfix}.{build}"


Reply = tuple[str, bool]
"""A dashboard reply line and whether the server then closes the connection."""


def _power_on(ctl: Controller) -> Reply:
    ctl.power_on()
    return "Powering on", False


def _power_off(ctl: Controller) -> Reply:
    ctl.power_off()
    return "Powering off", False


def _brake_release(ctl: Controller) -> Reply:
    ctl.brake_release()
    return "Brake releasing", False


def _close_popup(ctl: Controller) -> Reply:
    ctl.popup = None
    return "closing popup", False


def _close_safety_popup(ctl: Controller) -> Reply:
    ctl.safety_popup = None
    return "closing safety popup", False


def _restart_safety(ctl: Controller) -> Reply:
    ctl.restart_safety()
    return "Restarting safety", False


def _program_state(ctl: Controller) -> Reply:
    """``PLAYING``, ``PAUSED`` or ``STOPPED``, then the running or loaded program's name."""
    state = RuntimeState(ctl.runtime_state).name
    state = state if state in ("PLAYING", "PAUSED") else "STOPPED"
    name = ctl.program.name if ctl.program is not None else ctl.loaded_program
    return f"{state} {name}".rstrip(), False


def _stop(ctl: Controller) -> Reply:
    ctl.stop_program()
    return "Stopped", False


def _play(ctl: Controller) -> Reply:
    """Resume a paused program, else start the loaded ``.urp`` (an :class:`InstalledProgram`)."""
    if ctl.resume_program():
        return "Starting program", False
    if ctl.loaded_program and ctl.start_program(InstalledProgram(ctl.loaded_program)):
        return "Starting program", False
    return "Failed to execute: play", False


def _loaded_program(ctl: Controller) -> Reply:
    if ctl.loaded_program:
        return f"Loaded program: {ctl.loaded_program}", False
    return "No program loaded", False


_COMMANDS: dict[str, Callable[[Controller], Reply]] = {
    "quit": lambda ctl: ("Disconnected", True),
    "power on": _power_on,
    "power off": _power_off,
    "brake release": _brake_release,
    "unlock protective stop": lambda ctl: (ctl.unlock_protective_stop(), False),
    "close popup": _close_popup,
    "close safety popup": _close_safety_popup,
    "restart safety": _restart_safety,
    "robotmode": lambda ctl: (f"Robotmode: {RobotMode(ctl.robot_mode).name}", False),
    "safetymode": lambda ctl: (f"Safetymode: {SafetyMode(ctl.safety_mode).name}", False),
    "safetystatus": lambda ctl: (f"Safetystatus: {SafetyMode(ctl.safety_mode).name}", False),
    "programstate": _program_state,
    "running": lambda ctl: (
        f"Program running: {str(ctl.runtime_state == RuntimeState.PLAYING).lower()}",
        False,
    ),
    "polyscopeversion": lambda ctl: (f"URSoftware {software_version(ctl)} (Jan 01 2024)", False),
    "version": lambda ctl: (software_version(ctl), False),
    "is in remote control": lambda ctl: (str(ctl.remote_control).lower(), False),
    "get serial number": lambda ctl: (ctl.config.serial_number, False),
    "get robot model": lambda ctl: (ctl.spec.name.upper().rstrip("E"), False),
    "stop": _stop,
    "play": _play,
    "pause": lambda ctl: (
        "Pausing program" if ctl.pause_program() else "Failed to execute: pause",
        False,
    ),
    "get loaded program": _loaded_program,
    "isprogramsaved": lambda ctl: (f"true {ctl.loaded_program}".rstrip(), False),
    "get operational mode": lambda ctl: ("NONE", False),
    "clear operational mode": lambda ctl: (
        "operational mode is no longer controlled by Dashboard Server",
        False,
    ),
    "shutdown": lambda ctl: ("Shutting down", True),
}
"""The commands without an argument, by their lower-case text."""


def _show_popup(ctl: Controller, arg: str) -> Reply:
    ctl.popup = arg
    return "showing popup", False


def _load_program(ctl: Controller, arg: str) -> Reply:
    """Load a ``.urp`` by name; any other file is not found."""
    name = arg.strip()
    if not name.endswith(".urp"):
        return f"File not found: {name}", False
    ctl.loaded_program = name
    return f"Loading program: {name}", False


def _add_to_log(ctl: Controller, arg: str) -> Reply:
    ctl.add_log(f"dashboard: {arg}")
    return "Added log message", False


_ARGUMENT_COMMANDS: tuple[tuple[str, Callable[[Controller, str], Reply]], ...] = (
    ("popup ", _show_popup),
    ("load installation ", lambda ctl, arg: (f"Loading installation: {arg}", False)),
    ("load ", _load_program),
    ("addtolog ", _add_to_log),
    ("setuserrole ", lambda ctl, arg: (f"Setting user role: {arg}", False)),
    ("set operational mode ", lambda ctl, arg: (f"Setting operational mode: {arg}", False)),
)
"""The commands with an argument, by their lower-case prefix, the longest of a shared prefix
first; each gets the rest of the line as typed."""


def handle(ctl: Controller, line: str) -> Reply:
    """Reply to one dashboard command; returns ``(reply, close_connection)``.

    Call under ``ctl.lock``.
    """
    raw = line.strip()
    cmd = raw.lower()
    if not ctl.remote_control and any(cmd == c.strip() or cmd.startswith(c) for c in _REMOTE_ONLY):
        return NOT_IN_REMOTE, False
    command = _COMMANDS.get(cmd)
    if command is not None:
        return command(ctl)
    for prefix, with_argument in _ARGUMENT_COMMANDS:
        if cmd.startswith(prefix):
            return with_argument(ctl, raw[len(prefix) :])
    return f"could not understand: '{raw}'", False
