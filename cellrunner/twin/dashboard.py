"""Dashboard server (port 29999) commands and their replies, as a PolyScope 5 / CB3 gives them.

One command per line, case-insensitive; one reply line each. The greeting on connect is
:data:`GREETING`. Commands that act on the robot are refused with
:data:`NOT_IN_REMOTE` while the controller is in local control.
"""

from __future__ import annotations

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


def handle(ctl: Controller, line: str) -> tuple[str, bool]:
    """Reply to one dashboard command; returns ``(reply, close_connection)``.

    Call under ``ctl.lock``.
    """
    raw = line.strip()
    cmd = raw.lower()
    if not ctl.remote_control and any(cmd == c.strip() or cmd.startswith(c) for c in _REMOTE_ONLY):
        return NOT_IN_REMOTE, False
    if cmd == "quit":
        return "Disconnected", True
    if cmd == "power on":
        ctl.power_on()
        return "Powering on", False
    if cmd == "power off":
        ctl.power_off()
        return "Powering off", False
    if cmd == "brake release":
        ctl.brake_release()
        return "Brake releasing", False
    if cmd == "unlock protective stop":
        return ctl.unlock_protective_stop(), False
    if cmd == "close popup":
        ctl.popup = None
        return "closing popup", False
    if cmd == "close safety popup":
        ctl.safety_popup = None
        return "closing safety popup", False
    if cmd.startswith("popup "):
        ctl.popup = raw[6:]
        return "showing popup", False
    if cmd == "restart safety":
        ctl.restart_safety()
        return "Restarting safety", False
    if cmd == "robotmode":
        return f"Robotmode: {RobotMode(ctl.robot_mode).name}", False
    if cmd == "safetymode":
        return f"Safetymode: {SafetyMode(ctl.safety_mode).name}", False
    if cmd == "safetystatus":
        return f"Safetystatus: {SafetyMode(ctl.safety_mode).name}", False
    if cmd == "programstate":
        state = RuntimeState(ctl.runtime_state).name
        state = state if state in ("PLAYING", "PAUSED") else "STOPPED"
        name = ctl.program.name if ctl.program is not None else ctl.loaded_program
        return f"{state} {name}".rstrip(), False
    if cmd == "running":
        return f"Program running: {str(ctl.runtime_state == RuntimeState.PLAYING).lower()}", False
    if cmd == "polyscopeversion":
        return f"URSoftware {software_version(ctl)} (Jan 01 2024)", False
    if cmd == "version":
        return software_version(ctl), False
    if cmd == "is in remote control":
        return str(ctl.remote_control).lower(), False
    if cmd == "get serial number":
        return ctl.config.serial_number, False
    if cmd == "get robot model":
        return ctl.spec.name.upper().rstrip("E"), False
    if cmd == "stop":
        ctl.stop_program()
        return "Stopped", False
    if cmd == "play":
        if ctl.resume_program():
            return "Starting program", False
        if ctl.loaded_program and ctl.start_program(InstalledProgram(ctl.loaded_program)):
            return "Starting program", False
        return "Failed to execute: play", False
    if cmd == "pause":
        return ("Pausing program" if ctl.pause_program() else "Failed to execute: pause"), False
    if cmd.startswith("load installation "):
        return f"Loading installation: {raw[18:]}", False
    if cmd.startswith("load "):
        name = raw[5:].strip()
        if not name.endswith(".urp"):
            return f"File not found: {name}", False
        ctl.loaded_program = name
        return f"Loading program: {name}", False
    if cmd == "get loaded program":
        return (
            f"Loaded program: {ctl.loaded_program}" if ctl.loaded_program else "No program loaded"
        ), False
    if cmd == "isprogramsaved":
        return f"true {ctl.loaded_program}".rstrip(), False
    if cmd.startswith("addtolog "):
        ctl.add_log(f"dashboard: {raw[9:]}")
        return "Added log message", False
    if cmd.startswith("setuserrole "):
        return f"Setting user role: {raw[12:]}", False
    if cmd == "get operational mode":
        return "NONE", False
    if cmd == "clear operational mode":
        return "operational mode is no longer controlled by Dashboard Server", False
    if cmd.startswith("set operational mode "):
        return f"Setting operational mode: {raw[21:]}", False
    if cmd == "shutdown":
        return "Shutting down", True
    return f"could not understand: '{raw}'", False
