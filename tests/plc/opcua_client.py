"""An OPC UA client (asyncua) run as a separate process; prints one JSON object.

    python opcua_client.py --url URL --scenario connect|job|write \
        [--policy Basic256Sha256_SignAndEncrypt|none] [--cert C --key K] [--user U --password P]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import time
from typing import Any

CLIENT_URI = "urn:cellrunner:test-client"


async def connect(args: argparse.Namespace) -> Any:
    from asyncua import Client, ua
    from asyncua.crypto import security_policies as sp

    if args.force:  # a hostile client: ignore what the server offers, insist on ours
        original = Client.find_endpoint

        def lenient(endpoints: Any, mode: Any, uri: str) -> Any:
            try:
                return original(endpoints, mode, uri)
            except ua.UaError:
                import copy

                endpoint = copy.copy(endpoints[0])
                endpoint.SecurityMode, endpoint.SecurityPolicyUri = mode, uri
                return endpoint

        Client.find_endpoint = staticmethod(lenient)  # type: ignore[method-assign]
    client = Client(args.url, timeout=args.timeout)
    client.application_uri = CLIENT_URI
    client.session_timeout = 10_000
    if args.policy != "none":
        name, mode = args.policy.split("_")
        policy = getattr(sp, f"SecurityPolicy{name}")
        await client.set_security(
            policy, args.cert, args.key, mode=getattr(ua.MessageSecurityMode, mode)
        )
    if args.user:
        client.set_user(args.user)
        client.set_password(args.password)
    await client.connect()
    return client


class Events:
    def __init__(self) -> None:
        self.received: list[dict[str, Any]] = []

    def event_notification(self, event: Any) -> None:
        self.received.append(
            {"JobId": event.JobId, "ResultCode": event.ResultCode, "ClientJobId": event.ClientJobId}
        )


async def scenario_job(client: Any) -> dict[str, Any]:
    from asyncua import ua

    out: dict[str, Any] = {}
    ns = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{ns}:Cell")
    etype = await client.nodes.base_event_type.get_child(f"{ns}:JobCompletedEventType")
    on_cell, on_server = Events(), Events()
    sub1 = await client.create_subscription(20, on_cell)
    await sub1.subscribe_events(cell, etype)
    sub2 = await client.create_subscription(20, on_server)
    await sub2.subscribe_events(client.nodes.server, etype)

    async def start(task: str, params: str, cid: str) -> list[Any]:
        return await cell.call_method(f"{ns}:StartJob", task, params, cid)

    out["types"] = {}
    for name in (
        "State",
        "StateName",
        "Ready",
        "Busy",
        "ProtectiveStop",
        "EmergencyStop",
        "CurrentJobId",
        "CurrentStep",
        "ProdProcessed",
        "ProdDefective",
    ):
        dv = await (await cell.get_child(f"{ns}:{name}")).read_data_value()
        out["types"][name] = dv.Value.VariantType.name
    last = await cell.get_child(f"{ns}:LastJob")
    for name in (
        "JobId",
        "ResultCode",
        "ResultText",
        "CycleTime",
        "EndTime",
        "FailureKind",
        "FailureStep",
    ):
        dv = await (await last.get_child(f"{ns}:{name}")).read_data_value()
        out["types"]["LastJob." + name] = dv.Value.VariantType.name

    t0 = time.monotonic()
    out["first"] = await start("pick_place", '{"slot": 3}', "plc-job-1")
    out["start_latency_s"] = time.monotonic() - t0
    out["again"] = await start("pick_place", '{"slot": 3}', "plc-job-1")
    deadline = time.monotonic() + 5
    while (not on_cell.received or not on_server.received) and time.monotonic() < deadline:
        await asyncio.sleep(0.02)
    out["events_cell"] = on_cell.received
    out["events_server"] = on_server.received
    out["last_job"] = {
        name: str(await (await last.get_child(f"{ns}:{name}")).read_value())
        for name in ("JobId", "ResultCode", "ResultText")
    }
    out["prod_processed"] = await (await cell.get_child(f"{ns}:ProdProcessed")).read_value()
    # wait for Idle, then the rejects
    state = await cell.get_child(f"{ns}:Ready")
    while not await state.read_value() and time.monotonic() < deadline:
        await asyncio.sleep(0.02)
    out["again_after_end"] = await start("pick_place", '{"slot": 3}', "plc-job-1")
    out["unknown_task"] = await start("nope", "{}", "plc-job-2")
    out["bad_params"] = await start("pick_place", '{"slot": 99}', "plc-job-3")
    out["bad_json"] = await start("pick_place", "{slot: 1", "plc-job-4")
    out["by_number"] = await start("2", "", "plc-job-5")
    try:
        await cell.call_method(f"{ns}:Unhold")
        out["unhold_when_idle"] = "accepted"
    except ua.UaStatusCodeError as exc:
        out["unhold_when_idle"] = type(exc).__name__
    await sub1.delete()
    await sub2.delete()
    return out


async def scenario_run(client: Any, task: str, params: str, wait_s: float) -> dict[str, Any]:
    """StartJob once and wait for its completion event (a real cell's job takes seconds)."""
    ns = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{ns}:Cell")
    etype = await client.nodes.base_event_type.get_child(f"{ns}:JobCompletedEventType")
    events = Events()
    sub = await client.create_subscription(20, events)
    await sub.subscribe_events(cell, etype)
    job_id, code = await cell.call_method(f"{ns}:StartJob", task, params, "run-1")
    deadline = time.monotonic() + wait_s
    while not events.received and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
    last = await cell.get_child(f"{ns}:LastJob")
    out = {
        "job_id": job_id,
        "return_code": code,
        "events": events.received,
        "last_result": await (await last.get_child(f"{ns}:ResultCode")).read_value(),
        "cycle_time": await (await last.get_child(f"{ns}:CycleTime")).read_value(),
    }
    await sub.delete()
    return out


async def scenario_hold(client: Any) -> dict[str, Any]:
    """StartJob of the slow task, Hold over OPC UA: who the cell says holds it, then Abort."""
    ns = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{ns}:Cell")
    job_id, code = await cell.call_method(f"{ns}:StartJob", "slow", "", "hold-1")
    await asyncio.sleep(0.2)
    await cell.call_method(f"{ns}:Hold")
    source = await cell.get_child(f"{ns}:HoldSource")
    deadline = time.monotonic() + 5
    while not await source.read_value() and time.monotonic() < deadline:
        await asyncio.sleep(0.02)
    out = {
        "job": [job_id, code],
        "hold_source": await source.read_value(),
        "hold_reason": await (await cell.get_child(f"{ns}:HoldReason")).read_value(),
    }
    await cell.call_method(f"{ns}:Abort")
    return out


async def scenario_write(client: Any) -> dict[str, Any]:
    from asyncua import ua

    ns = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{ns}:Cell")
    out: dict[str, Any] = {}
    for name, value, vtype in (
        ("State", 6, ua.VariantType.Int32),
        ("Ready", True, ua.VariantType.Boolean),
    ):
        node = await cell.get_child(f"{ns}:{name}")
        try:
            await node.write_value(ua.DataValue(ua.Variant(value, vtype)))
            out[name] = "written"
        except ua.UaStatusCodeError as exc:
            out[name] = type(exc).__name__
    node = await (await cell.get_child(f"{ns}:LastJob")).get_child(f"{ns}:JobId")
    try:
        await node.write_value(ua.DataValue(ua.Variant("forged", ua.VariantType.String)))
        out["LastJob.JobId"] = "written"
    except ua.UaStatusCodeError as exc:
        out["LastJob.JobId"] = type(exc).__name__
    out["State_after"] = await (await cell.get_child(f"{ns}:State")).read_value()
    return out


async def scenario_hostile(client: Any) -> dict[str, Any]:
    """StartJob with what a careless or hostile client sends: wrong argument types,
    non-finite and deeply nested JSON, over-long strings."""
    from asyncua import ua

    ns = await client.get_namespace_index("urn:cellrunner")
    cell = await client.nodes.objects.get_child(f"{ns}:Cell")
    out: dict[str, Any] = {}

    async def call(name: str, *args: Any) -> Any:
        try:
            _job_id, code = await cell.call_method(f"{ns}:StartJob", *args)
            out[name] = code
        except ua.UaStatusCodeError as exc:
            out[name] = type(exc).__name__

    int32, null = ua.VariantType.Int32, ua.Variant(None, ua.VariantType.Null)
    await call("wrong_types", ua.Variant(1, int32), ua.Variant(2, int32), ua.Variant(3, int32))
    await call("null_parameters", "home", null, "x-null-1")
    await call("null_task", null, "{}", "x-null-2")
    await call("null_client_job_id", "home", "{}", null)
    await call("boolean_parameters", "home", ua.Variant(True, ua.VariantType.Boolean), "x-b")
    await call("thousand_digits", "pick_place", '{"slot": 1' + "0" * 1000 + "}", "x-digits")
    await call("thousand_digits_text", "pick_place", '{"slot": "1' + "0" * 1000 + '"}', "x-dt")
    await call("infinity", "pick_place", '{"slot": Infinity}', "h-1")
    await call("nan", "pick_place", '{"slot": NaN}', "h-2")
    await call("huge_number", "pick_place", '{"slot": 1e999}', "h-3")
    await call("deep_json", "pick_place", "[" * 100_000 + "]" * 100_000, "h-4")
    await call("long_client_id", "pick_place", "{}", "x" * 10_000_000)
    await call("long_task", "p" * 100_000, "{}", "h-5")
    await call("fine", "home", "{}", "h-6")
    return out


async def register_unauthenticated(url: str) -> str:
    """RegisterServer on a bare secure channel (no session, no user)."""
    from asyncua import Client, ua

    client = Client(url, timeout=4)
    await client.connect_socket()
    try:
        await client.send_hello()
        await client.open_secure_channel()
        server = ua.RegisteredServer()
        server.ServerUri = "urn:intruder"
        server.ProductUri = "urn:intruder"
        server.ServerNames = [ua.LocalizedText("intruder")]
        server.ServerType = ua.ApplicationType.Server
        server.DiscoveryUrls = [url]
        server.IsOnline = True
        try:
            await client.uaclient.register_server(server)
            return "accepted"
        except ua.UaStatusCodeError as exc:
            return type(exc).__name__
    finally:
        client.disconnect_socket()


async def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--scenario", default="connect")
    ap.add_argument("--policy", default="Basic256Sha256_SignAndEncrypt")
    ap.add_argument("--cert")
    ap.add_argument("--key")
    ap.add_argument("--user")
    ap.add_argument("--password")
    ap.add_argument("--force", action="store_true", help="skip the client's endpoint check")
    ap.add_argument("--task", default="pick_place")
    ap.add_argument("--params", default="{}")
    ap.add_argument("--wait", type=float, default=60.0)
    ap.add_argument("--timeout", type=float, default=4.0, help="per request, s")
    args = ap.parse_args()
    result: dict[str, Any] = {"connected": False}
    if args.scenario == "register":
        print(
            json.dumps({"register": await asyncio.wait_for(register_unauthenticated(args.url), 15)})
        )
        return
    try:
        client = await asyncio.wait_for(connect(args), 15)
    except Exception as exc:  # reported to the test
        result["error"] = f"{type(exc).__name__}: {exc}"
        print(json.dumps(result))
        return
    result["connected"] = True
    try:
        if args.scenario == "job":
            result.update(await asyncio.wait_for(scenario_job(client), 30))
        elif args.scenario == "run":
            result.update(
                await asyncio.wait_for(
                    scenario_run(client, args.task, args.params, args.wait), args.wait + 20
                )
            )
        elif args.scenario == "hostile":
            result.update(await asyncio.wait_for(scenario_hostile(client), 60))
        elif args.scenario == "hold":
            result.update(await asyncio.wait_for(scenario_hold(client), 15))
        elif args.scenario == "held":  # who holds the cell, as OPC UA publishes it
            ns = await client.get_namespace_index("urn:cellrunner")
            cell = await client.nodes.objects.get_child(f"{ns}:Cell")
            result["hold_source"] = await (await cell.get_child(f"{ns}:HoldSource")).read_value()
            result["hold_reason"] = await (await cell.get_child(f"{ns}:HoldReason")).read_value()
        elif args.scenario == "write":
            result.update(await asyncio.wait_for(scenario_write(client), 15))
        else:
            ns = await client.get_namespace_index("urn:cellrunner")
            cell = await client.nodes.objects.get_child(f"{ns}:Cell")
            result["state"] = await (await cell.get_child(f"{ns}:State")).read_value()
    finally:
        await client.disconnect()
    print(json.dumps(result, default=str))


if __name__ == "__main__":
    asyncio.run(main())
