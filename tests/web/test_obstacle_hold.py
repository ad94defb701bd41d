"""Holds say who held (issue 37): a real `cellrunner serve` of the watched demo cell on the
twin, a tote only its depth camera sees standing on the path for 4 s. While the arm waits
for it, the status page (status.json, over loopback HTTP) says the obstacle holds the job,
in the words of HoldSource.OBSTACLE with the voxel that stops it, not a PLC's Hold."""

from __future__ import annotations

import json
import time
import urllib.request

import pytest

from tests.web.plc_page import (
    DONE,
    ERROR,
    JOB_ACK,
    OBSTRUCTED,
    READY,
    serving_the_tote,
)

HOST = "127.0.0.147"


@pytest.fixture
def serving(tmp_path):
    with serving_the_tote(tmp_path, HOST) as served:
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
