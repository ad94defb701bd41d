"""An OPC UA client watching the cell, run as a separate process.

    python opcua_watch.py --url URL --user U --password P [--period 0.05]

Logs in (None policy), reads ``Cell.State`` every ``period`` s until stdin closes, then
prints one JSON object: ``{"reads", "errors", "max_gap_s", "states", "error_kinds"}`` -- the longest
time between two successful reads and every State value seen, in order of first sight.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import sys
import time


async def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--user", required=True)
    ap.add_argument("--password", required=True)
    ap.add_argument("--period", type=float, default=0.05)
    ap.add_argument("--max-s", type=float, default=300.0)
    args = ap.parse_args()
    logging.disable(logging.CRITICAL)
    from asyncua import Client

    for attempt in range(60):  # until the server listens (at most ~30 s)
        client = Client(args.url, timeout=4)
        client.set_user(args.user)
        client.set_password(args.password)
        try:
            await client.connect()
            break
        except (TimeoutError, OSError):
            if attempt == 59:
                raise
            await asyncio.sleep(0.5)
    ns = await client.get_namespace_index("urn:cellrunner")
    state = await (await client.nodes.objects.get_child(f"{ns}:Cell")).get_child(f"{ns}:State")
    loop = asyncio.get_running_loop()
    stdin_closed = loop.run_in_executor(None, sys.stdin.read)
    print(json.dumps({"started": True}), flush=True)
    reads = errors = 0
    kinds: list[str] = []
    states: list[int] = []
    last_ok = time.monotonic()
    max_gap = 0.0
    deadline = time.monotonic() + args.max_s
    while not stdin_closed.done() and time.monotonic() < deadline:
        try:
            value = await asyncio.wait_for(state.read_value(), 2.0)
            now = time.monotonic()
            max_gap, last_ok = max(max_gap, now - last_ok), now
            reads += 1
            if value not in states:
                states.append(value)
        except Exception as exc:  # counted, the first kinds named
            errors += 1
            if len(kinds) < 5 and type(exc).__name__ not in kinds:
                kinds.append(type(exc).__name__)
        await asyncio.sleep(args.period)
    await client.disconnect()
    print(
        json.dumps(
            {
                "reads": reads,
                "errors": errors,
                "max_gap_s": round(max_gap, 3),
                "states": states,
                "error_kinds": kinds,
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    asyncio.run(main())
