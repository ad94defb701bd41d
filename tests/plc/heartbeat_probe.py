"""An independent PLC watching the cell heartbeat, run as a separate process.

    python heartbeat_probe.py --host H --port P [--period 0.02] [--max-s 300]

Polls holding register 100 every ``period`` s with its own Modbus client (pyModbusTCP,
not the pymodbus the cell serves with) and keeps the PLC heartbeat (register 0) moving
every 100 ms, as a PLC does. Runs until stdin closes (or ``max-s``), then prints one
JSON object:

    {"samples", "changes", "read_errors", "max_gap_s", "max_read_s", "gaps": [[t_s, gap_s], ...]}

``max_gap_s`` is the longest time between two observed changes of register 100 (from the
first change on); ``gaps`` lists every gap over 150 ms with the time it ended, measured
from the probe's start.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", required=True)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--period", type=float, default=0.02)
    ap.add_argument("--max-s", type=float, default=300.0)
    args = ap.parse_args()
    from pyModbusTCP.client import ModbusClient

    client = ModbusClient(
        host=args.host, port=args.port, timeout=2.0, auto_open=True, auto_close=False
    )
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    t0 = time.monotonic()
    deadline = t0 + args.max_s
    samples = changes = errors = 0
    max_read_s = 0.0
    last_value: int | None = None
    last_change: float | None = None
    max_gap = 0.0
    gaps: list[list[float]] = []
    beat, beat_at = 0, 0.0
    print(json.dumps({"started": True}), flush=True)
    while not done.is_set() and time.monotonic() < deadline:
        t_read = time.monotonic()
        regs = client.read_holding_registers(100, 1)
        now = time.monotonic()
        max_read_s = max(max_read_s, now - t_read)
        samples += 1
        if not regs:
            errors += 1
        elif regs[0] != last_value:
            if last_value is not None:
                changes += 1
                if last_change is not None:
                    gap = now - last_change
                    max_gap = max(max_gap, gap)
                    if gap > 0.15:
                        gaps.append([round(now - t0, 3), round(gap, 3)])
                last_change = now
            last_value = regs[0]
        if now - beat_at >= 0.1:
            beat, beat_at = (beat + 1) % 65536, now
            client.write_single_register(0, beat)
        time.sleep(max(0.0, args.period - (time.monotonic() - t_read)))
    if last_change is not None:  # a heartbeat that stopped before the end is a gap too
        tail = time.monotonic() - last_change
        max_gap = max(max_gap, tail)
        if tail > 0.15:
            gaps.append([round(time.monotonic() - t0, 3), round(tail, 3)])
    print(
        json.dumps(
            {
                "samples": samples,
                "changes": changes,
                "read_errors": errors,
                "max_gap_s": round(max_gap, 3),
                "max_read_s": round(max_read_s, 3),
                "gaps": gaps,
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    main()
