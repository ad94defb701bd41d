"""Who the controller is, asked of its dashboard, and ur_rtde's errors in cellrunner's terms.

:func:`check_dashboard` refuses a controller whose model differs from the cell's
(:class:`ControllerMismatch`) and one in local control (:class:`RemoteControlOff`);
:func:`translate` turns ur_rtde's ``RuntimeError`` texts (and a socket's ``OSError``) into
cellrunner's errors through :data:`UR_RTDE_ERRORS`.
"""

from __future__ import annotations

import re
from typing import Any

from cellrunner.errors import BackendError, ControllerMismatch, PeerUnreachable, RemoteControlOff
from cellrunner.model.robots import RobotSpec

#: ur_rtde's RuntimeError texts -> (cellrunner error, message); the first marker found wins
UR_RTDE_ERRORS: tuple[tuple[str, type[BackendError] | type[PeerUnreachable], str], ...] = (
    ("Could not connect", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("Timeout connecting", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("End of file", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("connection", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("remote control", RemoteControlOff, "the controller at {host}: {text}"),
)


def _model_family(name: str) -> str:
    """``ur5e`` / ``UR5e`` / ``UR5`` -> ``UR5``."""
    return name.strip().upper().removesuffix("E")


def _serial_number(dashboard: Any) -> str:
    """The controller's serial number, "" when the dashboard does not give one (an old
    controller, an answer that is no number)."""
    try:
        text = str(dashboard.getSerialNumber()).strip()
    except RuntimeError:
        return ""
    return text if text.isalnum() else ""


def translate(host: str, exc: Exception) -> BackendError | PeerUnreachable:
    """ur_rtde's ``RuntimeError`` (or a socket's ``OSError``) as cellrunner's error,
    through :data:`UR_RTDE_ERRORS`."""
    text = str(exc)
    if isinstance(exc, OSError):
        return PeerUnreachable(f"cannot reach the robot controller at {host}: {text}")
    for marker, error, template in UR_RTDE_ERRORS:
        if marker in text:
            return error(template.format(host=host, text=text))
    return BackendError(f"ur_rtde: {text}")


def check_dashboard(
    dashboard: Any,
    host: str,
    spec: RobotSpec,
    versions: tuple[int, ...],
    *,
    require_remote_control: bool,
) -> tuple[str, str]:
    """The controller's (robot model, serial number) from its connected ``dashboard``;
    :class:`ControllerMismatch` if it drives another model than ``spec``,
    :class:`RemoteControlOff` if it is in local control (PolyScope 5.6 on)."""
    robot_model = dashboard.getRobotModel().strip()
    serial_number = _serial_number(dashboard)
    expected = _model_family(spec.name)
    # the dashboard answers "UR5" for a UR5 and a UR5e alike (the generation is checked
    # beforehand); a reply that names no model is not held against the robot
    reported = _model_family(robot_model)
    if re.fullmatch(r"UR\d+", reported) and reported != expected:
        raise ControllerMismatch(
            f"the controller at {host} drives a {robot_model} "
            f"but the cell's robot is {spec.name} ({expected})"
        )
    if (
        require_remote_control
        and versions[0] == 5
        and versions[1] >= 6
        and not dashboard.isInRemoteControl()
    ):
        raise RemoteControlOff(
            f"the controller at {host} is in local control; "
            "switch the teach pendant to Remote Control"
        )
    return robot_model, serial_number
