"""The measured belt speed reaches the PLC (SPEC section 13): ``serve`` on the twin, whose
belt runs at the reference cell's speed_max (0.30 m/s), read over Modbus TCP by an
independent client (pyModbusTCP): register 114, mm/s."""

from __future__ import annotations

import signal
import time
from pathlib import Path

from tests.conftest import ROOT
from tests.rig import free_port, modbus_client, start_serve

HOST = "127.0.0.6"


def test_register_114_reads_the_belt_speed_in_mm_per_s(tmp_path: Path) -> None:
    port = free_port(HOST)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = (ROOT / "cells" / "conveyor_pick_ur10e.yaml").read_text()
    cell += f"plc:\n  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 2.0}}\n"
    (tmp_path / "cells" / "c.yaml").write_text(cell)
    task = (ROOT / "tasks" / "conveyor_pick.yaml").read_text()
    (tmp_path / "tasks" / "conveyor_pick.yaml").write_text(task)
    proc = start_serve(tmp_path / "cells" / "c.yaml")
    try:
        client = modbus_client(port, HOST)
        seen: list[int] = []
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            regs = client.read_holding_registers(114, 1)
            if regs:
                seen.append(regs[0])
                if len(seen) >= 5 and all(295 <= v <= 305 for v in seen[-5:]):
                    break
            time.sleep(0.1)
        assert len(seen) >= 5 and all(295 <= v <= 305 for v in seen[-5:]), seen[-10:]
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
