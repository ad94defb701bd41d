"""Holds say who held (issue 37): a real `cellrunner serve` of the watched demo cell on the
twin, a tote only its depth camera sees standing on the path for 4 s. While the arm waits
for it, the status page (status.json, over loopback HTTP) says the obstacle holds the job,
in the words of HoldSource.OBSTACLE with the voxel that stops it, not a PLC's Hold."""

from __future__ import annotations

import json
import time
import urllib.request

import pytest

from tests.rig import free_port
from tests.web.plc_page import (
    DONE,
    ERROR,
    JOB_ACK,
    OBSTRUCTED,
    READY,
    TOTE,
    heartbeat,
    serve_with_page,
)

HOST = "127.0.0.147"


@pytest.fixture
def serving(tmp_path):
    from tests.conftest import ROOT

    modbus_port, http_port = free_port(HOST), free_port(HOST)
    text = (ROOT / "cells" / "watched_ur5e.yaml").read_text()
    text = text.replace(
        "sim:\n  depth_noise: 0.002\n", f"sim:\n  depth_noise: 0.002\n  intruders:\n    - {TOTE}\n"
    )
    text = text.replace("tasks/pick_place_watched.yaml", "tasks/pick_place.yaml")
    text = text.replace("tasks/", f"{ROOT}/tasks/").replace("var/", f"{tmp_path}/")
    text = text.replace("bind: 127.0.0.1, port: 1503", f"bind: {HOST}, port: {modbus_port}")
    text = text.split("  opcua:")[0] + f"journal: {tmp_path}/jobs.sqlite\n"
    cell = tmp_path / "watched.yaml"
    cell.write_text(text)
    with (
        serve_with_page(cell, HOST, modbus_port, http_port) as served,
        heartbeat(HOST, modbus_port),
    ):
        yield served


def test_an_obstacle_on_the_path_holds_as_obstacle_on_the_page(serving):
    url, plc = serving
    plc.wait(READY, 60)
    plc.client.write_multiple_registers(2, [78, 1])
    plc.client.write_single_register(1, 1)  # JOB_REQ
    plc.wait(JOB_ACK, 10)
    holders: set[tuple[str, str]] = set()
    obstructed_seen = False
    regs = None
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        with urllib.request.urlopen(url + "status.json", timeout=5) as res:
            snap = json.loads(res.read())
        if snap.get("hold_source"):
            holders.add((snap["hold_source"], snap["hold_reason"]))
        regs = plc.poll()
        if regs and regs[1] & OBSTRUCTED:
            obstructed_seen = True
        if regs and regs[1] & (DONE | ERROR):
            break
        time.sleep(0.05)
    # it waited for the tote: done (0) once it left, or 108 when a loaded machine let the
    # wait run out first (SPEC 12); either way the obstacle, no one else, held it
    assert regs is not None and regs[4] == 78 and regs[5] in (0, 108), regs
    assert obstructed_seen, "Modbus never showed OBSTRUCTED while the arm waited"
    assert holders, "the page never said who held the job"
    # the obstacle; a protective stop too if, on a loaded machine, the arm touched the tote
    sources = {source for source, _ in holders}
    assert "obstacle" in sources and sources <= {"obstacle", "protective_stop"}, holders
    for source, reason in holders:
        if source == "obstacle":
            assert reason.startswith("obstacle in the watched zone: "), reason
            assert "occupied voxel at (" in reason, reason
    plc.client.write_single_register(1, 0)
