"""Who held the cell: each hold carries its source, so the log, the journal, the status
page and OPC UA tell a PLC's Hold from its watchdog, an operator, an obstacle and a
protective stop (the night shift asks who stopped the cell).

The words of a PLC's Hold and of a protective stop are those the log always had
(``hold requested``, ``protective stop``); the others are new."""

from __future__ import annotations

import enum


class HoldSource(enum.StrEnum):
    """Where a hold came from; the value is the ``source`` field of the log's ``hold``
    event, the journal's held step and the status (``hold_source``)."""

    PLC = "plc"  # the PLC's Hold command (Modbus command bit)
    PLC_WATCHDOG = "plc_watchdog"  # the PLC's heartbeat stopped (Modbus watchdog)
    OPCUA = "opcua"  # an operator or client calling Hold over OPC UA
    PAGE = "page"  # an operator on the status page
    OBSTACLE = "obstacle"  # the arm waits for an obstacle of the watched zone
    PROTECTIVE_STOP = "protective_stop"  # the controller's protective stop

    @property
    def reason(self) -> str:
        """The hold's reason in words (the log's ``reason``)."""
        return _REASONS[self]

    @classmethod
    def named(cls, name: str) -> HoldSource:
        """The source called ``name``; a ValueError naming the known ones otherwise."""
        try:
            return cls(name)
        except ValueError:
            known = ", ".join(s.value for s in cls)
            # ValueError, as the enum's own lookup raises (this one names the known sources)
            raise ValueError(f"unknown hold source {name!r}; known: {known}") from None


_REASONS = {
    HoldSource.PLC: "hold requested",
    HoldSource.PLC_WATCHDOG: "PLC watchdog: the heartbeat stopped",
    HoldSource.OPCUA: "hold requested over OPC UA",
    HoldSource.PAGE: "hold requested on the status page",
    HoldSource.OBSTACLE: "obstacle in the watched zone",
    HoldSource.PROTECTIVE_STOP: "protective stop",
}
