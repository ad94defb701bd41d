"""The PLC link alarms of :mod:`cellrunner.web.alarms`, for known and new protocols."""

from __future__ import annotations

from cellrunner.model.cellport import CellStatus
from cellrunner.model.codes import PackMLState
from cellrunner.web.alarms import active_alarms

IDLE = CellStatus(state=int(PackMLState.IDLE), state_name="Idle", ready=True, busy=False)


def test_a_known_link_down_says_what_to_check() -> None:
    (alarm,) = active_alarms(IDLE, {"opcua": False})
    assert (alarm.severity, alarm.title) == ("warning", "PLC link down (opcua)")
    assert alarm.detail == "No OPC UA client is connected."


def test_a_link_of_a_protocol_the_texts_do_not_know_is_still_an_alarm() -> None:
    (alarm,) = active_alarms(IDLE, {"profinet": False, "modbus": True})
    assert (alarm.severity, alarm.title) == ("warning", "PLC link down (profinet)")
    assert alarm.detail == "The profinet link has no peer."
    assert alarm.fix.startswith("Check that the PLC or client program runs")
