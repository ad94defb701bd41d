"""A generic OPC UA client (asyncua) in its own process, as an MES or a SCADA would be: it
knows only the companion specifications' namespace URIs and BrowseNames (OPC 40010
Robotics, OPC 30050 PackML, ISA-95 job control / Machinery Jobs), finds the objects by
browsing from Objects for their types, and prints one JSON object.

    python companion_client.py --url URL --scenario browse|orders|abort|viewer \
        [--policy Basic256Sha256_SignAndEncrypt|none] [--cert C --key K] --user U --password P
        [--task NAME] [--params JSON] [--order ID] [--wait S]

Only ``--cell`` reads a cellrunner name (``Objects/Cell/LastJob``), to compare.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import time
from typing import Any

ROBOTICS = "http://opcfoundation.org/UA/Robotics/"
DI = "http://opcfoundation.org/UA/DI/"
PACKML = "http://opcfoundation.org/UA/PackML/"
ISA95 = "http://opcfoundation.org/UA/ISA95-JOBCONTROL_V2/"
JOBS = "http://opcfoundation.org/UA/Machinery/Jobs/"
MACHINERY = "http://opcfoundation.org/UA/Machinery/"
MAX_BROWSED = 400  # nodes looked at while searching for a type's instance


async def connect(args: argparse.Namespace) -> Any:
    from asyncua import Client, ua
    from asyncua.crypto import security_policies as sp

    client = Client(args.url, timeout=30)
    client.application_uri = "urn:cellrunner:test-client"
    if args.policy != "none":
        name, mode = args.policy.split("_")
        await client.set_security(
            getattr(sp, f"SecurityPolicy{name}"),
            args.cert,
            args.key,
            mode=getattr(ua.MessageSecurityMode, mode),
        )
    client.set_user(args.user)
    client.set_password(args.password)
    await client.connect()
    await client.load_data_type_definitions()
    return client


async def find_instance(client: Any, uri: str, type_name: str) -> Any:
    """The first object below Objects whose type is ``uri``'s ``type_name`` (breadth
    first, at most MAX_BROWSED nodes)."""
    from asyncua import ua

    ns = await client.get_namespace_index(uri)
    wanted = ua.QualifiedName(type_name, ns)
    queue, seen = [client.nodes.objects], 0
    while queue and seen < MAX_BROWSED:
        node = queue.pop(0)
        for child in await node.get_children(nodeclassmask=ua.NodeClass.Object):
            seen += 1
            typedef = await child.read_type_definition()
            if (
                typedef is not None
                and typedef.NamespaceIndex != 0
                and await client.get_node(typedef).read_browse_name() == wanted
            ):
                return child
            queue.append(child)
    raise LookupError(f"no {type_name} of {uri} below Objects")


async def path(client: Any, node: Any, *steps: tuple[str, str]) -> Any:
    """``node``'s descendant along (namespace URI, BrowseName) steps (TranslateBrowsePath)."""
    names = [f"{await client.get_namespace_index(uri)}:{name}" for uri, name in steps]
    return await node.get_child(names)


async def children(node: Any) -> list[Any]:
    from asyncua import ua

    return list(await node.get_children(nodeclassmask=ua.NodeClass.Object))


async def entry_points(client: Any) -> dict[str, list[str]]:
    """What Objects/Machines (OPC 40001-1) and Objects/DeviceSet (DI) organize: the
    type names of the objects there."""
    out = {}
    for uri, name in ((MACHINERY, "Machines"), (DI, "DeviceSet")):
        folder = await path(client, client.nodes.objects, (uri, name))
        out[name] = [
            (await client.get_node(await c.read_type_definition()).read_browse_name()).Name
            for c in await children(folder)
        ]
    return out


# -- what an MES reads -------------------------------------------------------------------
async def read_robotics(client: Any) -> dict[str, Any]:
    system = await find_instance(client, ROBOTICS, "MotionDeviceSystemType")
    out: dict[str, Any] = {}
    devices = await children(await path(client, system, (ROBOTICS, "MotionDevices")))
    arm = devices[0]
    out["model"] = (await (await path(client, arm, (DI, "Model"))).read_value()).Text
    out["serial"] = await (await path(client, arm, (DI, "SerialNumber"))).read_value()
    arm_type = client.get_node(await arm.read_type_definition())
    out["arm_type_members"] = sorted(
        [(await c.read_browse_name()).Name for c in await arm_type.get_children()]
    )
    axes = await children(await path(client, arm, (ROBOTICS, "Axes")))
    out["axes"] = [(await a.read_browse_name()).Name for a in axes]
    positions = []
    for _ in range(2):
        row = []
        for axis in axes:
            params = await path(client, axis, (DI, "ParameterSet"))
            position = await (await path(client, params, (ROBOTICS, "ActualPosition"))).read_value()
            speed = await (await path(client, params, (ROBOTICS, "ActualSpeed"))).read_value()
            row.append([position, speed])
        positions.append(row)
        await asyncio.sleep(0.3)
    out["positions"] = positions
    controller = (await children(await path(client, system, (ROBOTICS, "Controllers"))))[0]
    task = (await children(await path(client, controller, (ROBOTICS, "TaskControls"))))[0]
    out["task_program"] = await (
        await path(client, task, (DI, "ParameterSet"), (ROBOTICS, "TaskProgramName"))
    ).read_value()
    safety = (await children(await path(client, system, (ROBOTICS, "SafetyStates"))))[0]
    for name in ("EmergencyStop", "ProtectiveStop"):
        out[name] = await (
            await path(client, safety, (DI, "ParameterSet"), (ROBOTICS, name))
        ).read_value()
    return out


async def read_packml(client: Any) -> dict[str, Any]:
    packml = await find_instance(client, PACKML, "PackMLBaseObjectType")
    out: dict[str, Any] = {}
    machines = [
        [(PACKML, "BaseStateMachine")],
        [(PACKML, "BaseStateMachine"), (PACKML, "MachineState")],
        [(PACKML, "BaseStateMachine"), (PACKML, "MachineState"), (PACKML, "ExecuteState")],
    ]
    out["states"] = []
    for steps in machines:
        current = await path(
            client, packml, *steps, ("http://opcfoundation.org/UA/", "CurrentState")
        )
        number = await path(client, current, ("http://opcfoundation.org/UA/", "Number"))
        out["states"].append([(await current.read_value()).Text, await number.read_value()])
    admin = await path(client, packml, (PACKML, "Admin"))
    for name in ("ProdProcessedCount", "ProdDefectiveCount"):
        counts = await (await path(client, admin, (PACKML, name))).read_value()
        out[name] = [c.Count for c in counts]
    reason = await (await path(client, admin, (PACKML, "StopReason"))).read_value()
    out["StopReason"] = [reason.ID, reason.Message]
    status = await path(client, packml, (PACKML, "Status"))
    for name in ("UnitModeCurrent", "MachSpeed"):
        out[name] = await (await path(client, status, (PACKML, name))).read_value()
    return out


# -- job orders ------------------------------------------------------------------------
class StatusEvents:
    def __init__(self) -> None:
        self.received: list[list[Any]] = []

    def event_notification(self, event: Any) -> None:
        order_id = getattr(event.JobOrder, "JobOrderID", None)
        self.received.append([order_id, [s.StateNumber for s in event.JobState or []]])


async def job_management(client: Any) -> tuple[Any, Any]:
    manager = await find_instance(client, JOBS, "JobManagementType")
    control = await path(client, manager, (JOBS, "JobOrderControl"))
    results = await path(client, manager, (JOBS, "JobOrderResults"))
    return control, results


def job_order(order_id: str, task: str, params: dict[str, Any]) -> Any:
    from asyncua import ua

    parameter = ua.ISA95ParameterDataType
    values = []
    for name, value in params.items():
        kind = ua.VariantType.Int32 if isinstance(value, int) else ua.VariantType.Double
        if isinstance(value, str):
            kind = ua.VariantType.String
        values.append(parameter(ID=name, Value=ua.Variant(value, kind)))
    return ua.ISA95JobOrderDataType(
        JobOrderID=order_id,
        WorkMasterID=[ua.ISA95WorkMasterDataType(ID=task)],
        JobOrderParameters=values,
    )


async def call(client: Any, node: Any, method: str, *args: Any) -> Any:
    from asyncua import ua

    ns = await client.get_namespace_index(ISA95)
    return await node.call_method(
        f"{ns}:{method}", *args, ua.Variant([], ua.VariantType.LocalizedText)
    )


async def response(client: Any, results: Any, order_id: str) -> Any:
    ns = await client.get_namespace_index(ISA95)
    return await results.call_method(f"{ns}:RequestJobResponseByJobOrderID", order_id)


def summary(resp: Any) -> dict[str, Any]:
    data = {p.ID: p.Value.Value for p in resp.JobResponseData or []}
    return {
        "order": resp.JobOrderID,
        "states": [s.StateNumber for s in resp.JobState or []],
        "state_names": [s.StateText.Text for s in resp.JobState or []],
        "data": {k: v for k, v in data.items() if isinstance(v, int | float | str)},
        "start": str(resp.StartTime),
        "end": str(resp.EndTime),
    }


async def scenario_orders(client: Any, args: argparse.Namespace) -> dict[str, Any]:
    from asyncua import ua

    out: dict[str, Any] = {}
    control, results = await job_management(client)
    isa = await client.get_namespace_index(ISA95)
    etype = client.get_node(ua.NodeId(1006, isa))
    events = StatusEvents()
    sub = await client.create_subscription(20, events)
    await sub.subscribe_events(client.nodes.server, etype)
    system = await find_instance(client, ROBOTICS, "MotionDeviceSystemType")
    controller = (await children(await path(client, system, (ROBOTICS, "Controllers"))))[0]
    task = (await children(await path(client, controller, (ROBOTICS, "TaskControls"))))[0]
    program = await path(client, task, (DI, "ParameterSet"), (ROBOTICS, "TaskProgramName"))
    arm = (await children(await path(client, system, (ROBOTICS, "MotionDevices"))))[0]
    base = (await children(await path(client, arm, (ROBOTICS, "Axes"))))[0]
    base_position = await path(client, base, (DI, "ParameterSet"), (ROBOTICS, "ActualPosition"))

    params = json.loads(args.params)
    first = job_order(args.order, args.task, params)
    out["store_and_start"] = await call(client, control, "StoreAndStart", ua.Variant(first))
    programs: set[str] = set()
    positions: list[float] = []
    deadline = time.monotonic() + args.wait
    while time.monotonic() < deadline:
        programs.add(await program.read_value())
        positions.append(await base_position.read_value())
        resp, _ = await response(client, results, args.order)
        if resp.JobState and resp.JobState[0].StateNumber in (5, 6):
            break
        await asyncio.sleep(0.05)
    out["task_programs"] = sorted(programs)
    out["base_positions"] = positions
    out["first"] = summary(resp)
    out["again"] = await call(client, control, "StoreAndStart", ua.Variant(first))
    out["again_response"] = summary((await response(client, results, args.order))[0])
    # a second order, stored, aborted before it starts, cleared
    second = job_order(args.order + "-b", args.task, params)
    out["store"] = await call(client, control, "Store", ua.Variant(second))
    out["stored"] = summary((await response(client, results, args.order + "-b"))[0])
    out["abort"] = await call(client, control, "Abort", args.order + "-b")
    out["aborted"] = summary((await response(client, results, args.order + "-b"))[0])
    out["start_aborted"] = await call(client, control, "Start", args.order + "-b")
    out["clear"] = await call(client, control, "Clear", args.order + "-b")
    out["unknown"] = await call(client, control, "Start", "no-such-order")
    ended = ua.ISA95StateDataType(
        BrowsePath=ua.RelativePath(), StateText=ua.LocalizedText("Ended"), StateNumber=5
    )
    by_state, _ = await results.call_method(
        f"{isa}:RequestJobResponseByJobOrderState", ua.Variant([ended])
    )
    out["ended_orders"] = [r.JobOrderID for r in by_state]
    listed = await (await path(client, control, (ISA95, "JobOrderList"))).read_value()
    out["list"] = [[x.JobOrder.JobOrderID, [s.StateNumber for s in x.State]] for x in listed]
    masters = await (await path(client, control, (ISA95, "WorkMaster"))).read_value()
    out["work_masters"] = [[w.ID, [p.ID for p in w.Parameters or []]] for w in masters]
    await asyncio.sleep(0.3)
    out["events"] = events.received
    if args.cell:
        own = await client.get_namespace_index("urn:cellrunner")
        last = await client.nodes.objects.get_child([f"{own}:Cell", f"{own}:LastJob"])
        out["cell_last_job"] = await (await last.get_child(f"{own}:JobId")).read_value()
    return out


async def scenario_abort(client: Any, args: argparse.Namespace) -> dict[str, Any]:
    """StoreAndStart an order, Abort it once it runs, read how it ended."""
    from asyncua import ua

    control, results = await job_management(client)
    order = job_order(args.order, args.task, json.loads(args.params))
    out: dict[str, Any] = {
        "store_and_start": await call(client, control, "StoreAndStart", ua.Variant(order))
    }
    seen: list[int] = []
    deadline = time.monotonic() + args.wait
    while time.monotonic() < deadline:
        state = (await response(client, results, args.order))[0].JobState[0].StateNumber
        seen.append(state)
        if state == 3 and "abort" not in out:  # Running: abort it
            out["abort"] = await call(client, control, "Abort", args.order)
        if state in (5, 6):
            break
        await asyncio.sleep(0.05)
    out["seen"] = sorted(set(seen))
    out["ended"] = summary((await response(client, results, args.order))[0])
    out["abort_again"] = await call(client, control, "Abort", args.order)
    return out


async def scenario_viewer(client: Any, args: argparse.Namespace) -> dict[str, Any]:
    from asyncua import ua

    out: dict[str, Any] = {}
    control, results = await job_management(client)

    async def attempt(coro: Any) -> str:
        try:
            await coro
        except ua.UaStatusCodeError as exc:
            return type(exc).__name__
        return "called"

    order = job_order(args.order, args.task, json.loads(args.params))
    out["store_and_start"] = await attempt(
        call(client, control, "StoreAndStart", ua.Variant(order))
    )
    out["abort"] = await attempt(call(client, control, "Abort", args.order))
    own = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{own}:Cell")
    out["cell_start_job"] = await attempt(
        cell.call_method(f"{own}:StartJob", args.task, "{}", "v-1")
    )
    out["cell_hold"] = await attempt(cell.call_method(f"{own}:Hold"))
    out["response_by_id"] = await attempt(response(client, results, args.order))
    out["packml"] = await read_packml(client)
    return out


async def main(args: argparse.Namespace) -> dict[str, Any]:
    out: dict[str, Any] = {"connected": False}
    for attempt in range(3):  # a loaded machine may drop a first handshake
        try:
            client = await connect(args)
            break
        except Exception as exc:
            out["error"] = f"{type(exc).__name__}: {exc}"
            if attempt == 2:
                return out
            await asyncio.sleep(1.0)
    out.pop("error", None)
    out["connected"] = True
    try:
        if args.scenario == "browse":
            out["entry_points"] = await entry_points(client)
            out["robotics"] = await read_robotics(client)
            out["packml"] = await read_packml(client)
        elif args.scenario == "orders":
            out.update(await scenario_orders(client, args))
        elif args.scenario == "abort":
            out.update(await scenario_abort(client, args))
        elif args.scenario == "viewer":
            out.update(await scenario_viewer(client, args))
    except Exception as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    finally:
        await client.disconnect()
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument(
        "--scenario", choices=("browse", "orders", "abort", "viewer"), required=True
    )
    parser.add_argument("--policy", default="Basic256Sha256_SignAndEncrypt")
    parser.add_argument("--cert")
    parser.add_argument("--key")
    parser.add_argument("--user", required=True)
    parser.add_argument("--password", required=True)
    parser.add_argument("--task", default="pick_place")
    parser.add_argument("--params", default="{}")
    parser.add_argument("--order", default="MES-1")
    parser.add_argument("--wait", type=float, default=30.0)
    parser.add_argument("--cell", action="store_true")
    arguments = parser.parse_args()
    print(json.dumps(asyncio.run(asyncio.wait_for(main(arguments), 150)), default=str))
