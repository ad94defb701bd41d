"""The RTDE input watchdog of the virtual controller: a running program stops when its
watched input register was not written at the rate the client asked for."""

from __future__ import annotations

from typing import Any


def check_watchdog(ctl: Any) -> None:
    """Stop the program of ``ctl`` (a :class:`~.controller.Controller`) when its watched
    input register is overdue."""
    if ctl.watchdog is None or ctl.program is None:
        return
    name, min_hz = ctl.watchdog
    last = ctl.last_input_write.get(name, -1e9)
    if ctl.time_s - last > 1.0 / min_hz:
        ctl.add_log(f"RTDE watchdog: {name} not updated at {min_hz} Hz; program stopped")
        ctl._halt_program("rtde watchdog")
