"""ISA-95 job orders over OPC UA (OPC 10031-4 V2 as OPC 40001-3 Machinery Job Management
uses it): the address space of :class:`~cellrunner.plc.job_orders.OrderBook`.

::

    <machine>/JobManagement                    (Machinery/Jobs: JobManagementType)
      JobOrderControl                          (ISA95JobOrderReceiverObjectType)
        JobOrderList  ISA95JobOrderAndStateDataType[]     the orders and their states
        WorkMaster    ISA95WorkMasterDataType[]           the tasks and their params
        MaxDownloadableJobOrders UInt16
        Store(JobOrder, Comment) StoreAndStart(...) -> ReturnStatus UInt64
        Start(JobOrderID, Comment) Abort(...) Clear(...) -> ReturnStatus
        RevokeStart(...) Cancel(...) Pause(...) Resume(...) -> ReturnStatus
      JobOrderResults                          (ISA95JobResponseProviderObjectType)
        JobOrderResponseList ISA95JobResponseDataType[]
        RequestJobResponseByJobOrderID(JobOrderID) -> (JobResponse, ReturnStatus)
        RequestJobResponseByJobOrderState(JobOrderState[]) -> (JobResponses[], ReturnStatus)

Every change of an order's state raises an ISA95JobOrderStatusEventType (JobOrder,
JobResponse, JobState) on JobOrderControl and the Server object. A job's response
carries JobResponseData ``ResultCode`` (Int32, SPEC 7), ``ResultText``, ``CycleTime``
(Double, s), ``JobId`` (the cell's) and ``Task``.

The types are declared from the specification's tables in
:mod:`cellrunner.plc.opcua_isa95_types` (asyncua cannot import the Machinery Jobs
nodeset, its issue 1869).
"""

from __future__ import annotations

import logging
from typing import Any

from cellrunner.model.cellport import CellPort, CellStatus, JobResult, JobSource, TaskCatalog
from cellrunner.plc.job_orders import (
    MAX_OPEN_ORDERS,
    STATE_NAMES,
    JobOrder,
    OrderBook,
    ReturnStatus,
    parse_request,
)
from cellrunner.plc.opcua_isa95_types import (
    DATATYPES,
    JOB_MANAGEMENT_TYPE,
    PROVIDER_TYPE,
    RECEIVER_TYPE,
    STATUS_EVENT_TYPE,
)
from cellrunner.plc.opcua_isa95_types import declare_types as declare_types
from cellrunner.plc.opcua_nodes import (
    Instances,
    Values,
    add_method,
    argument,
    eu_information,
    node_id,
    qname,
)

_log = logging.getLogger(__name__)


class JobOrderServer:
    """The job orders' nodes, methods and events on one OPC UA server."""

    def __init__(self, port: CellPort, source: JobSource) -> None:
        self.book = OrderBook(port, source)
        self._isa = self._jobs = 0
        self._values: Values | None = None
        self._events: Any = None
        self.reading_methods: list[Any] = []

    async def build(self, server: Any, machine: Any, own: int, isa: int, jobs: int) -> None:
        """JobManagement under ``machine`` (types from :func:`declare_types`, their Python
        classes loaded)."""
        from asyncua import ua

        self._isa, self._jobs = isa, jobs
        nodes = Instances(own, "JobManagement")
        manager = await nodes.obj(
            machine, "Self", "JobManagement", jobs, node_id(JOB_MANAGEMENT_TYPE, jobs)
        )
        control = await nodes.obj(
            manager, "JobOrderControl", "JobOrderControl", jobs, node_id(RECEIVER_TYPE, isa)
        )
        results = await nodes.obj(
            manager, "JobOrderResults", "JobOrderResults", jobs, node_id(PROVIDER_TYPE, isa)
        )

        def dt(name: str) -> Any:
            return node_id(DATATYPES[name][0], isa)

        c = "JobOrderControl."
        await nodes.var(
            control, c + "JobOrderList", "JobOrderList", isa, [], "ExtensionObject",
            datatype=dt("ISA95JobOrderAndStateDataType"), key="JobOrderList",
        )  # fmt: skip
        await nodes.var(
            control, c + "WorkMaster", "WorkMaster", isa, self._work_masters(), "ExtensionObject",
            datatype=dt("ISA95WorkMasterDataType"),
        )  # fmt: skip
        for name in (
            "EquipmentID",
            "MaterialClassID",
            "MaterialDefinitionID",
            "PersonnelID",
            "PhysicalAssetID",
        ):
            await nodes.var(control, c + name, name, isa, [], "String")
        await nodes.var(
            control, c + "MaxDownloadableJobOrders", "MaxDownloadableJobOrders", isa,
            MAX_OPEN_ORDERS, "UInt16", prop=True,
        )  # fmt: skip
        await nodes.var(
            results, "JobOrderResults.JobOrderResponseList", "JobOrderResponseList", isa, [],
            "ExtensionObject", datatype=dt("ISA95JobResponseDataType"), key="JobOrderResponseList",
        )  # fmt: skip
        order, comment = (
            argument("JobOrder", dt("ISA95JobOrderDataType")),
            argument("Comment", "LocalizedText", array=True),
        )
        order_id = argument("JobOrderID", "String")
        status = argument("ReturnStatus", "UInt64")
        for name, handler, inputs in (
            ("Store", self._store(start=False), [order, comment]),
            ("StoreAndStart", self._store(start=True), [order, comment]),
            ("Start", self._command(self.book.start), [order_id, comment]),
            ("Abort", self._command(self.book.abort), [order_id, comment]),
            ("Clear", self._command(self.book.clear), [order_id, comment]),
            ("RevokeStart", self._command(self.book.revoke_start), [order_id, comment]),
            ("Cancel", self._command(self.book.cancel), [order_id, comment]),
            ("Pause", self._command(self.book.pause), [order_id, comment]),
            ("Resume", self._command(self.book.resume), [order_id, comment]),
        ):
            await add_method(control, own, c + name, name, isa, handler, inputs, [status])
        by_id = await add_method(
            results, own, "JobOrderResults.RequestJobResponseByJobOrderID",
            "RequestJobResponseByJobOrderID", isa, self._response_by_id, [order_id],
            [argument("JobResponse", dt("ISA95JobResponseDataType")), status],
        )  # fmt: skip
        by_state = await add_method(
            results, own, "JobOrderResults.RequestJobResponseByJobOrderState",
            "RequestJobResponseByJobOrderState", isa, self._responses_by_state,
            [argument("JobOrderState", dt("ISA95StateDataType"), array=True)],
            [argument("JobResponses", dt("ISA95JobResponseDataType"), array=True), status],
        )  # fmt: skip
        self.reading_methods = [by_id.nodeid, by_state.nodeid]
        await control.set_event_notifier([ua.EventNotifier.SubscribeToEvents])
        self._events = await server.get_event_generator(node_id(STATUS_EVENT_TYPE, isa), control)
        self._values = Values(server, nodes.variables)

    # -- keeping up with the cell ----------------------------------------------------------
    async def follow(self, status: CellStatus) -> None:
        self.book.follow(status)
        await self._publish()

    async def finish(self, result: JobResult) -> None:
        self.book.finish(result)
        await self._publish()

    async def _publish(self, *, lists: bool = False) -> None:
        """The lists written and one event per order whose state changed (with ``lists``
        the lists are written even when no state changed: an order was cleared)."""
        changed = self.book.take_changes()
        if (not changed and not lists) or self._values is None:
            return
        await self._values.write(
            {
                "JobOrderList": [self._order_and_state(o) for o in self.book.orders.values()],
                "JobOrderResponseList": [
                    self._response(o) for o in self.book.orders.values() if o.job_id
                ],
            }
        )
        for order, state in changed:
            await self._raise_event(order.at(state))

    async def _raise_event(self, order: JobOrder) -> None:
        from asyncua import ua

        gen = self._events
        gen.event.JobOrder = self._original(order)
        gen.event.JobResponse = self._response(order)
        gen.event.JobState = self._states(order)
        gen.event.Severity = 100 if order.state != 6 else 500
        await gen.trigger(message=f"job order {order.order_id}: {STATE_NAMES[order.state]}")
        source = gen.event.emitting_node
        gen.event.emitting_node = node_id(ua.object_ids.ObjectIds.Server)
        try:  # the same event for clients subscribed on the Server object
            await gen.isession.subscription_service.trigger_event(gen.event)
        finally:
            gen.event.emitting_node = source

    # -- methods -----------------------------------------------------------------------------
    def _store(self, *, start: bool) -> Any:
        async def call(parent: Any, *args: Any) -> Any:
            from asyncua import ua

            status = ReturnStatus.INVALID_REQUEST
            order = getattr(args[0], "Value", None) if args else None
            if order is not None and hasattr(order, "JobOrderID"):
                request = parse_request(
                    str(order.JobOrderID or ""),
                    [str(w.ID or "") for w in (order.WorkMasterID or [])],
                    [
                        (str(p.ID or ""), getattr(p.Value, "Value", p.Value))
                        for p in (order.JobOrderParameters or [])
                    ],
                    order.Priority,
                    order,
                )
                if isinstance(request, str):
                    _log.warning("job order refused: %s", request)
                    status = ReturnStatus.UNABLE_TO_ACCEPT_JOB_ORDER
                else:
                    status = self.book.store(request, start=start)
                    await self._publish()
            return [ua.Variant(int(status), ua.VariantType.UInt64)]

        return call

    def _command(self, command: Any) -> Any:
        async def call(parent: Any, *args: Any) -> Any:
            from asyncua import ua

            order_id = getattr(args[0], "Value", None) if args else None
            if not isinstance(order_id, str):
                status = ReturnStatus.INVALID_REQUEST
            else:
                status = command(order_id)
                await self._publish(lists=True)
            return [ua.Variant(int(status), ua.VariantType.UInt64)]

        return call

    async def _response_by_id(self, parent: Any, *args: Any) -> Any:
        from asyncua import ua

        order_id = getattr(args[0], "Value", None) if args else None
        order = self.book.find(order_id) if isinstance(order_id, str) else None
        response_type = getattr(ua, "ISA95JobResponseDataType")  # noqa: B009 - loaded type
        if order is None:
            status = (
                ReturnStatus.UNKNOWN_JOB_ORDER_ID
                if isinstance(order_id, str)
                else ReturnStatus.INVALID_REQUEST
            )
            return [ua.Variant(response_type()), ua.Variant(int(status), ua.VariantType.UInt64)]
        return [
            ua.Variant(self._response(order)),
            ua.Variant(int(ReturnStatus.NO_ERROR), ua.VariantType.UInt64),
        ]

    async def _responses_by_state(self, parent: Any, *args: Any) -> Any:
        from asyncua import ua

        wanted = getattr(args[0], "Value", None) if args else None
        if not isinstance(wanted, list) or not wanted:
            return [
                ua.Variant([], ua.VariantType.ExtensionObject),
                ua.Variant(int(ReturnStatus.INVALID_REQUEST), ua.VariantType.UInt64),
            ]
        # a state and, optionally, its sub-state (the standard's state path)
        numbers = [int(s.StateNumber or 0) for s in wanted]
        found = self.book.in_state([(numbers[0], numbers[1] if len(numbers) > 1 else None)])
        return [
            ua.Variant([self._response(o) for o in found], ua.VariantType.ExtensionObject),
            ua.Variant(int(ReturnStatus.NO_ERROR), ua.VariantType.UInt64),
        ]

    # -- the standard's structures --------------------------------------------------------
    def _work_masters(self) -> list[Any]:
        """What may be ordered: each task (its name the work master's ID) and its params."""
        from asyncua import ua

        port = self.book.port
        if not isinstance(port, TaskCatalog):
            return []
        work_master = getattr(ua, "ISA95WorkMasterDataType")  # noqa: B009 - loaded type
        param = getattr(ua, "ISA95ParameterDataType")  # noqa: B009 - loaded type
        return [
            work_master(
                ID=name,
                Parameters=[param(ID=p, Value=ua.Variant()) for p in port.task_params(name) or []],
            )
            for name in port.task_names()
        ]

    def _original(self, order: JobOrder) -> Any:
        from asyncua import ua

        if order.request.original is not None:
            return order.request.original
        return getattr(ua, "ISA95JobOrderDataType")(JobOrderID=order.order_id)  # noqa: B009

    def _states(self, order: JobOrder) -> list[Any]:
        from asyncua import ua

        state_type = getattr(ua, "ISA95StateDataType")  # noqa: B009 - loaded type
        path: list[Any] = []
        states = []
        for name, number in (
            (STATE_NAMES[order.state], int(order.state)),
            *([order.substate] if order.substate else []),
        ):
            element = ua.RelativePathElement(
                ReferenceTypeId=node_id(ua.object_ids.ObjectIds.HasComponent),
                IsInverse=False,  # type: ignore[arg-type]  # asyncua's Boolean is bool
                IncludeSubtypes=True,  # type: ignore[arg-type]
                TargetName=qname(name, self._isa),
            )
            path = [*path, element]
            states.append(
                state_type(
                    BrowsePath=ua.RelativePath(Elements=path),
                    StateText=ua.LocalizedText(name),
                    StateNumber=ua.UInt32(number),
                )
            )
        return states

    def _order_and_state(self, order: JobOrder) -> Any:
        from asyncua import ua

        both = getattr(ua, "ISA95JobOrderAndStateDataType")  # noqa: B009 - loaded type
        return both(JobOrder=self._original(order), State=self._states(order))

    def _response(self, order: JobOrder) -> Any:
        from asyncua import ua

        response_type = getattr(ua, "ISA95JobResponseDataType")  # noqa: B009 - loaded type
        param = getattr(ua, "ISA95ParameterDataType")  # noqa: B009 - loaded type
        result = order.result
        data = [
            param(ID="JobId", Value=ua.Variant(order.job_id, ua.VariantType.String)),
            param(ID="Task", Value=ua.Variant(str(order.request.task), ua.VariantType.String)),
        ]
        if result is not None:
            data += [
                param(
                    ID="ResultCode", Value=ua.Variant(int(result.result_code), ua.VariantType.Int32)
                ),
                param(ID="ResultText", Value=ua.Variant(result.result_text, ua.VariantType.String)),
                param(
                    ID="CycleTime",
                    Value=ua.Variant(float(result.cycle_time_s), ua.VariantType.Double),
                    EngineeringUnits=eu_information("SEC", "s", "second"),
                ),
            ]
        return response_type(
            JobResponseID=order.job_id or order.order_id,
            Description=ua.LocalizedText(result.result_text if result else ""),
            JobOrderID=order.order_id,
            StartTime=order.start_time,
            EndTime=order.end_time,
            JobState=self._states(order),
            JobResponseData=data,
        )
