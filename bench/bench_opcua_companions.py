"""How fresh the plant's language is (SPEC 13) and what it costs the PLC link.

    PYTHONPATH=. python bench/bench_opcua_companions.py [--seconds 5] [--jobs 20]

A FakeCell behind the real OPC UA server in this process; in a client process (asyncua)
over loopback: a subscription (publishing interval 20 ms, sampling as fast as the
server refreshes) on the arm's Base axis ActualPosition (OPC 40010) while a job turns it,
then ``--jobs`` ``Cell.StartJob`` calls, each timed, and as many ISA-95 StoreAndStart
calls. Prints a table: the interval between the axis' updates (median, p95; the issue's
target is 10 Hz, 100 ms at most), and the StartJob and StoreAndStart round trips
(median, p95) with their ratio.
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

ROBOTICS = "http://opcfoundation.org/UA/Robotics/"
DI = "http://opcfoundation.org/UA/DI/"
ISA95 = "http://opcfoundation.org/UA/ISA95-JOBCONTROL_V2/"
JOBS = "http://opcfoundation.org/UA/Machinery/Jobs/"


async def client_main(url: str, seconds: float, jobs: int) -> dict[str, Any]:
    from asyncua import Client, ua

    client = Client(url, timeout=30)
    client.set_user("bench")
    client.set_password("bench password")
    async with client:
        await client.load_data_type_definitions()
        own = await client.get_namespace_index("urn:cellrunner")
        rob, di = [await client.get_namespace_index(u) for u in (ROBOTICS, DI)]
        isa, jm = [await client.get_namespace_index(u) for u in (ISA95, JOBS)]
        machine = await client.nodes.objects.get_child(f"{own}:bench")
        base = await machine.get_child(
            [f"{own}:MotionDeviceSystem", f"{rob}:MotionDevices", f"{own}:Arm", f"{rob}:Axes",
             f"{own}:Base", f"{di}:ParameterSet", f"{rob}:ActualPosition"]
        )  # fmt: skip
        cell = await client.nodes.objects.get_child(f"{own}:Cell")
        control = await machine.get_child([f"{jm}:JobManagement", f"{jm}:JobOrderControl"])
        seen: list[float] = []

        class Handler:
            def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
                seen.append(time.monotonic())

        sub = await client.create_subscription(20, Handler())
        await sub.subscribe_data_change(base, sampling_interval=0)
        await cell.call_method(f"{own}:StartJob", "long", "{}", "bench-long")
        await asyncio.sleep(seconds)
        await sub.delete()
        start_job, store = [], []
        for i in range(jobs):
            await _wait_ready(cell, own)
            t0 = time.monotonic()
            await cell.call_method(f"{own}:StartJob", "home", "{}", f"bench-{i}")
            start_job.append(time.monotonic() - t0)
        for i in range(jobs):
            order = ua.ISA95JobOrderDataType(
                JobOrderID=f"order-{i}", WorkMasterID=[ua.ISA95WorkMasterDataType(ID="home")]
            )
            t0 = time.monotonic()
            await control.call_method(
                f"{isa}:StoreAndStart", order, ua.Variant([], ua.VariantType.LocalizedText)
            )
            store.append(time.monotonic() - t0)
    gaps = [b - a for a, b in itertools.pairwise(seen)]
    return {"gaps": gaps, "start_job": start_job, "store_and_start": store}


async def _wait_ready(cell: Any, own: int) -> None:
    ready = await cell.get_child(f"{own}:Ready")
    deadline = time.monotonic() + 30
    while not await ready.read_value() and time.monotonic() < deadline:
        await asyncio.sleep(0.02)


def p95(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))] if ordered else float("nan")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--jobs", type=int, default=20)
    parser.add_argument("--client", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client:
        print(json.dumps(asyncio.run(client_main(args.client, args.seconds, args.jobs))))
        return 0

    from cellrunner.plc.fake import FakeCell, FakeTask
    from cellrunner.plc.service import PlcService
    from cellrunner.plc.users import add_user
    from tests.rig import free_port

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        add_user(root / "users.yaml", "bench", "bench password")
        url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
        tasks = [FakeTask(1, "long", (), (args.seconds + 2,)), FakeTask(2, "home", (), (0.01,))]
        cell = FakeCell(tasks=tasks).start()
        config = {"opcua": {"endpoint": url, "security": ["none"], "users": "users.yaml"}}
        service = PlcService(cell, config, base_dir=root, cell_name="bench")
        t0 = time.monotonic()
        service.start()
        startup_s = time.monotonic() - t0
        try:
            run = subprocess.run(
                [sys.executable, __file__, "--client", url, "--seconds", str(args.seconds),
                 "--jobs", str(args.jobs)],
                capture_output=True, text=True, timeout=120 + args.seconds + args.jobs,
            )  # fmt: skip
        finally:
            service.stop()
            cell.close()
    lines = [line for line in run.stdout.splitlines() if line.startswith("{")]
    if not lines:
        print(run.stderr[-2000:], file=sys.stderr)
        return 1
    out = json.loads(lines[-1])
    rows = [
        ("axis update interval (ms)", out["gaps"], 100.0),
        ("Cell.StartJob round trip (ms)", out["start_job"], None),
        ("StoreAndStart round trip (ms)", out["store_and_start"], None),
    ]
    print(f"OPC UA server start with the companion objects: {startup_s:.2f} s")
    print(f"{'measure':32} {'n':>5} {'median':>8} {'p95':>8} {'target':>8}")
    for name, values, target in rows:
        ms = [v * 1000 for v in values]
        med = statistics.median(ms) if ms else float("nan")
        shown = "" if target is None else f"{target:.0f}"
        print(f"{name:32} {len(ms):5d} {med:8.1f} {p95(ms):8.1f} {shown:>8}")
    start, store = (statistics.median(out[k]) for k in ("start_job", "store_and_start"))
    print(f"StoreAndStart / StartJob median ratio: {store / start:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
