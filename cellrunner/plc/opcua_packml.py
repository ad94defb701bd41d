"""PackML over OPC UA (OPC 30050): the cell's state machine (SPEC 6, the numbers the
Modbus PackML register shows), its mode, its speed and its admin counters.

::

    <machine>/PackML                          (PackMLBaseObjectType)
      TagID, PackMLVersion
      Status      UnitModeCurrent Int32 (1 Production), MachSpeed, CurMachSpeed Float
                  (jobs per minute: the last cycle's rate; CurMachSpeed 0 out of Execute),
                  EquipmentBlocked, EquipmentStarved Boolean
      Admin       ProdProcessedCount, ProdDefectiveCount PackMLCountDataType[] (the
                  journal's counters: they survive a restart), StopReason
                  PackMLAlarmDataType (the last job that ended with a fault: its result
                  code, text and time)
      BaseStateMachine    CurrentState (Aborted, Aborting or Cleared) + Number
        MachineState      CurrentState (Stopped, Stopping, Clearing or Running) + Number
          ExecuteState    CurrentState (Idle, Starting, Execute, Held...) + Number

Each CurrentState's Number is the PackML state number (OPC 30050 uses ISA-TR88's, those of
SPEC 6); a machine whose parent is not in the state that contains it shows "" and 0.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from cellrunner.model.cellport import CellStatus, JobResult, PackMLState
from cellrunner.plc.opcua_nodes import (
    PACKML_URI,
    Field,
    Instances,
    Values,
    declare_object_type,
    declare_struct,
    eu_information,
    node_id,
)

S = PackMLState
_COUNT_TYPE, _COUNT_ENCODING = 14, 69
_ALARM_TYPE, _ALARM_ENCODING = 15, 74
_OBJECT_TYPES = {  # name: (id, base: None = BaseObjectType, or a state machine)
    "PackMLExecuteStateMachineType": (1, True),
    "PackMLMachineStateMachineType": (2, True),
    "PackMLBaseStateMachineType": (3, True),
    "PackMLStatusObjectType": (4, False),
    "PackMLAdminObjectType": (5, False),
    "PackMLBaseObjectType": (6, False),
}
_FINITE_STATE_MACHINE_TYPE = 2771
#: PackML's unit mode Production
PRODUCTION = 1
#: the state OPC 30050 numbers 19 and 18 (the machines that contain the others)
CLEARED, RUNNING = 19, 18
_BASE_STATES = {S.ABORTED, S.ABORTING}
_MACHINE_STATES = {S.STOPPED, S.STOPPING, S.CLEARING}
_INT32_MAX = 2**31 - 1
NULL_TIME = datetime(1601, 1, 1, tzinfo=UTC)


async def declare_types(server: Any) -> int:
    """Register PackML's namespace and declare its types; its namespace index."""
    ns: int = await server.register_namespace(PACKML_URI)
    eu = node_id(887)
    await declare_struct(
        server,
        ns,
        _COUNT_TYPE,
        _COUNT_ENCODING,
        "PackMLCountDataType",
        [
            Field("ID", "Int32"),
            Field("Name", "String"),
            Field("Unit", eu),
            Field("Count", "Int32"),
            Field("AccCount", "Int32"),
        ],
    )
    await declare_struct(
        server,
        ns,
        _ALARM_TYPE,
        _ALARM_ENCODING,
        "PackMLAlarmDataType",
        [
            Field("ID", "Int32"),
            Field("Value", "Int32"),
            Field("Message", "String"),
            Field("Category", "Int32"),
            Field("DateTime", "DateTime"),
            Field("AckDateTime", "DateTime"),
            Field("Trigger", "Boolean"),
        ],
    )
    for name, (ident, machine) in _OBJECT_TYPES.items():
        base = node_id(_FINITE_STATE_MACHINE_TYPE) if machine else None
        await declare_object_type(server, ns, ident, name, base)
    return ns


def state_path(state: int) -> list[tuple[str, int]]:
    """(name, number) of the current state of BaseStateMachine, MachineState and
    ExecuteState for the cell's PackML ``state`` ("" and 0 where a machine is inactive)."""
    try:
        current = S(state)
    except ValueError:
        return [("", 0), ("", 0), ("", 0)]
    none = ("", 0)
    named = (current.name.capitalize(), int(current))
    if current in _BASE_STATES:
        return [named, none, none]
    cleared = ("Cleared", CLEARED)
    if current in _MACHINE_STATES:
        return [cleared, named, none]
    return [cleared, ("Running", RUNNING), named]


class PackMLObject:
    """The PackML object of one OPC UA server, kept current from the cell's status."""

    def __init__(self) -> None:
        self._values: Values | None = None
        self._stop_reason: JobResult | None = None
        self._rate_per_min = 0.0

    async def build(self, server: Any, machine: Any, own: int, ns: int, tag: str) -> None:
        from asyncua import ua

        nodes = Instances(own, "PackML")

        def t(name: str) -> Any:
            return node_id(_OBJECT_TYPES[name][0], ns)

        root = await nodes.obj(machine, "Self", "PackML", own, t("PackMLBaseObjectType"))
        await nodes.var(root, "TagID", "TagID", ns, tag, "String", prop=True)
        await nodes.var(root, "PackMLVersion", "PackMLVersion", ns, "1.00", "String", prop=True)
        status = await nodes.obj(root, "Status", "Status", ns, t("PackMLStatusObjectType"))
        for name, vtype, value in (
            ("UnitModeCurrent", "Int32", PRODUCTION),
            ("MachSpeed", "Float", 0.0),
            ("CurMachSpeed", "Float", 0.0),
            ("EquipmentBlocked", "Boolean", False),
            ("EquipmentStarved", "Boolean", False),
        ):
            await nodes.var(status, f"Status.{name}", name, ns, value, vtype, key=name)
        admin = await nodes.obj(root, "Admin", "Admin", ns, t("PackMLAdminObjectType"))
        count_type, alarm_type = node_id(_COUNT_TYPE, ns), node_id(_ALARM_TYPE, ns)
        for name in ("ProdProcessedCount", "ProdDefectiveCount"):
            await nodes.var(
                admin, f"Admin.{name}", name, ns, [], "ExtensionObject",
                datatype=count_type, key=name,
            )  # fmt: skip
        await nodes.var(
            admin, "Admin.StopReason", "StopReason", ns, self._alarm(None), "ExtensionObject",
            datatype=alarm_type, key="StopReason",
        )  # fmt: skip
        parent = root
        for path, name, type_name in (
            ("BaseStateMachine", "BaseStateMachine", "PackMLBaseStateMachineType"),
            ("BaseStateMachine.MachineState", "MachineState", "PackMLMachineStateMachineType"),
            (
                "BaseStateMachine.MachineState.ExecuteState",
                "ExecuteState",
                "PackMLExecuteStateMachineType",
            ),
        ):
            parent = await nodes.obj(parent, path, name, ns, t(type_name))
            # a state machine's instance has its CurrentState (FiniteStateMachineType's)
            current = await parent.get_child("0:CurrentState")
            nodes.variables[f"{path}.CurrentState"] = (current, ua.VariantType.LocalizedText)
            await nodes.var(
                current, f"{path}.CurrentState.Number", "Number", 0, 0, "UInt32", prop=True,
                key=f"{path}.Number",
            )  # fmt: skip
        self._values = Values(server, nodes.variables)

    def finish(self, result: JobResult) -> None:
        if result.result_code >= 100:
            self._stop_reason = result
        if result.cycle_time_s > 0 and result.result_code < 10:
            self._rate_per_min = 60.0 / result.cycle_time_s

    async def publish(self, status: CellStatus) -> None:
        from asyncua import ua

        if self._values is None:
            return
        last = status.last_result
        if self._stop_reason is None and last is not None and last.result_code >= 100:
            self._stop_reason = last  # after a restart: the journal's last result
        if not self._rate_per_min and last is not None and last.cycle_time_s > 0:
            self._rate_per_min = 60.0 / last.cycle_time_s
        values: dict[str, Any] = {
            "MachSpeed": self._rate_per_min,
            "CurMachSpeed": self._rate_per_min if status.state == S.EXECUTE else 0.0,
            "EquipmentBlocked": status.obstructed,
            "EquipmentStarved": False,
            "ProdProcessedCount": [self._count(1, "parts processed", status.parts_processed)],
            "ProdDefectiveCount": [self._count(2, "parts defective", status.parts_defective)],
            "StopReason": self._alarm(self._stop_reason),
        }
        paths = (
            "BaseStateMachine",
            "BaseStateMachine.MachineState",
            "BaseStateMachine.MachineState.ExecuteState",
        )
        for path, (name, number) in zip(paths, state_path(status.state), strict=True):
            values[f"{path}.CurrentState"] = ua.LocalizedText(name)
            values[f"{path}.Number"] = ua.UInt32(number)
        await self._values.write(values)

    @staticmethod
    def _count(ident: int, name: str, count: int) -> Any:
        from asyncua import ua

        count_type = getattr(ua, "PackMLCountDataType")  # noqa: B009 - loaded type
        bounded = min(max(count, 0), _INT32_MAX)
        return count_type(
            ID=ident,
            Name=name,
            Unit=eu_information("H87", "pcs", "piece"),
            Count=bounded,
            AccCount=bounded,
        )

    @staticmethod
    def _alarm(result: JobResult | None) -> Any:
        from asyncua import ua

        alarm_type = getattr(ua, "PackMLAlarmDataType")  # noqa: B009 - loaded type
        if result is None:
            return alarm_type(DateTime=NULL_TIME, AckDateTime=NULL_TIME)
        return alarm_type(
            ID=int(result.result_code),
            Value=int(result.result_code),
            Message=result.result_text,
            Category=int(result.result_code) // 100 * 100,
            DateTime=result.end_time or NULL_TIME,
            AckDateTime=NULL_TIME,
            Trigger=True,
        )
