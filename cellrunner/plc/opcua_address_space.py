"""``Objects/Cell`` (namespace ``urn:cellrunner``, SPEC 8): its variables, read-only for
clients and written only when a value changes, and its JobCompletedEventType event."""

from __future__ import annotations

from typing import Any

from cellrunner.plc.opcua_config import NULL_DATETIME
from cellrunner.plc.opcua_conveyors import ConveyorNodes
from cellrunner.plc.opcua_methods import CellMethods
from cellrunner.plc.opcua_ua import node_id
from cellrunner.plc.port import CellStatus, JobResult, ResultCode

# (browse name, VariantType name, initial value) of Objects/Cell's variables
_CELL_VARIABLES = (
    ("State", "Int32", 0),
    ("StateName", "String", ""),
    ("Ready", "Boolean", False),
    ("Busy", "Boolean", False),
    ("ProtectiveStop", "Boolean", False),
    ("EmergencyStop", "Boolean", False),
    ("Obstructed", "Boolean", False),
    ("HoldSource", "String", ""),  # who holds the cell (HoldSource's value), "" when none
    ("HoldReason", "String", ""),
    ("CurrentJobId", "String", ""),
    ("CurrentStep", "Int32", 0),
    ("ProdProcessed", "UInt32", 0),
    ("ProdDefective", "UInt32", 0),
)
_LAST_JOB_VARIABLES = (
    ("JobId", "String", ""),
    ("ResultCode", "Int32", 0),
    ("ResultText", "String", ""),
    ("CycleTime", "Double", 0.0),
    ("EndTime", "DateTime", NULL_DATETIME),
    # why the planner refused the job ("" / 0 for any other end): its kind and 1-based step
    ("FailureKind", "String", ""),
    ("FailureStep", "Int32", 0),
)

_MISSING = object()


class CellObject:
    """The ``Cell`` object of one server: built once, then its values written."""

    def __init__(self) -> None:
        self._aspace: Any = None
        self._nodes: dict[str, Any] = {}
        self._types: dict[str, Any] = {}
        self._values: dict[str, Any] = {}
        self._event: Any = None
        self._conveyors: ConveyorNodes | None = None

    async def build(self, server: Any, idx: int, methods: CellMethods) -> None:
        """Add ``Objects/Cell`` (namespace index ``idx``), its variables, ``methods`` and
        the completion event to the (not yet started) ``server``."""
        from asyncua import ua

        self._aspace = server.iserver.aspace
        cell = await server.nodes.objects.add_object(
            node_id("Cell", idx), ua.QualifiedName("Cell", idx)
        )
        last = await cell.add_object(node_id("Cell.LastJob", idx), ua.QualifiedName("LastJob", idx))
        self._conveyors = ConveyorNodes(cell, idx, self._nodes, self._types)
        for parent, prefix, table in (
            (cell, "", _CELL_VARIABLES),
            (last, "LastJob.", _LAST_JOB_VARIABLES),
        ):
            for name, vtype, initial in table:
                key = prefix + name
                variant_type = getattr(ua.VariantType, vtype)
                node = await parent.add_variable(
                    node_id(f"Cell.{key}", idx),
                    ua.QualifiedName(name, idx),
                    initial,
                    variant_type,
                )
                self._nodes[key] = node
                self._types[key] = variant_type
        await methods.add_to(cell, idx)
        string, int32 = ua.VariantType.String, ua.VariantType.Int32
        etype = await server.create_custom_event_type(
            idx,
            "JobCompletedEventType",
            ua.object_ids.ObjectIds.BaseEventType,
            [
                ("JobId", string),
                ("ResultCode", int32),
                ("ResultText", string),
                ("ClientJobId", string),
            ],
        )
        self._event = await server.get_event_generator(etype, cell)
        await server.nodes.server.set_event_notifier([ua.EventNotifier.SubscribeToEvents])

    def status_values(self, status: CellStatus, *, initial: bool = False) -> dict[str, Any]:
        """The variables' values of ``status`` (on the first write, the last job's too)."""
        values = {
            "State": status.state,
            "StateName": status.state_name,
            "Ready": status.ready,
            "Busy": status.busy,
            "ProtectiveStop": status.protective_stop,
            "EmergencyStop": status.estop,
            "Obstructed": status.obstructed,
            "HoldSource": status.hold_source,
            "HoldReason": status.hold_reason,
            "CurrentJobId": status.job_id,
            "CurrentStep": status.step_index,
            "ProdProcessed": min(max(status.parts_processed, 0), 0xFFFFFFFF),
            "ProdDefective": min(max(status.parts_defective, 0), 0xFFFFFFFF),
        }
        if initial and status.last_result is not None:
            values.update(last_job_values(status.last_result))
        return values

    async def conveyor_values(self, status: CellStatus) -> dict[str, Any]:
        """``Cell.Conveyors.<name>.Speed`` (SPEC 13, mm/s), their nodes made as they appear."""
        if self._conveyors is None:
            return {}
        return dict(await self._conveyors.values(status.conveyor_speeds_mmps))

    async def write_values(self, values: dict[str, Any]) -> None:
        from asyncua import ua

        aspace = self._aspace
        for key, value in values.items():
            if self._values.get(key, _MISSING) == value:
                continue
            self._values[key] = value
            variant = ua.Variant(value, self._types[key])
            await aspace.write_attribute_value(
                self._nodes[key].nodeid, ua.attribute_ids.AttributeIds.Value, ua.DataValue(variant)
            )

    async def trigger_completion(self, result: JobResult) -> None:
        from asyncua import ua

        gen = self._event
        gen.event.JobId = result.job_id
        gen.event.ResultCode = int(result.result_code)  # the wire
        gen.event.ResultText = result.result_text
        gen.event.ClientJobId = result.client_job_id
        gen.event.Severity = 100 if result.result_code == ResultCode.OK else 500
        await gen.trigger(message=f"job {result.job_id} ended with {int(result.result_code)}")
        # the same event (same EventId) for clients subscribed on the Server object
        cell_node = gen.event.emitting_node
        gen.event.emitting_node = node_id(ua.object_ids.ObjectIds.Server)
        try:
            await gen.isession.subscription_service.trigger_event(gen.event)
        finally:
            gen.event.emitting_node = cell_node


def last_job_values(result: JobResult) -> dict[str, Any]:
    failure = result.failure
    return {
        "LastJob.JobId": result.job_id,
        "LastJob.ResultCode": int(result.result_code),  # the wire
        "LastJob.ResultText": result.result_text,
        "LastJob.CycleTime": float(result.cycle_time_s),
        "LastJob.EndTime": result.end_time or NULL_DATETIME,
        "LastJob.FailureKind": failure.kind.value if failure else "",
        "LastJob.FailureStep": (failure.step_index or 0) if failure else 0,
    }
