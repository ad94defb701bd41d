"""The measured belt speed reaches the PLC (SPEC section 13): ``serve`` on the twin, whose
belt runs at the reference cell's speed_max (0.30 m/s), read over Modbus TCP by an
independent client (pyModbusTCP): register 114, mm/s; and OPC UA's
``Cell.Conveyors.<name>.Speed`` read by an asyncua client."""

from __future__ import annotations

import asyncio
import dataclasses
import signal
import time
from pathlib import Path

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.opcua import NAMESPACE_URI
from cellrunner.plc.port import CellStatus
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user
from tests.conftest import ROOT
from tests.plc.conftest import PASSWORD, USER, plc_test_tasks
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


class _BeltCell(FakeCell):
    """A cell whose belt the engine measures at ``speed_mmps``."""

    speed_mmps = 250

    def status(self) -> CellStatus:
        return dataclasses.replace(
            super().status(), conveyor_speeds_mmps=(("belt", self.speed_mmps),)
        )


async def _read_speed(url: str) -> list[int]:
    """Cell.Conveyors.belt.Speed read by an OPC UA client over TCP, twice 1 s apart (the
    cell's speed changes in between)."""
    from asyncua import Client

    client = Client(url, timeout=5)
    client.set_user(USER)
    client.set_password(PASSWORD)
    seen = []
    async with client:
        idx = await client.get_namespace_index(NAMESPACE_URI)
        node = client.get_node(f"ns={idx};s=Cell.Conveyors.belt.Speed")
        for _ in range(50):  # until the first value is published (at most 5 s)
            try:
                seen.append(int(await node.read_value()))
                break
            except Exception:
                await asyncio.sleep(0.1)
        _BeltCell.speed_mmps = -120
        for _ in range(50):
            value = int(await node.read_value())
            if value == -120:
                seen.append(value)
                break
            await asyncio.sleep(0.1)
    return seen


def test_opcua_gives_each_belt_speed_in_mm_per_s(tmp_path: Path) -> None:
    users = tmp_path / "users.yaml"
    add_user(users, USER, PASSWORD)
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    config = {
        "opcua": {
            "endpoint": url,
            "users": str(users),
            "security": ["none"],
            "pki": str(tmp_path / "pki"),
        }
    }
    _BeltCell.speed_mmps = 250
    with _BeltCell(tasks=plc_test_tasks()) as cell, PlcService(cell, config):
        seen = asyncio.run(_read_speed(url))
    assert seen == [250, -120]
