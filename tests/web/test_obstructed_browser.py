"""A real `cellrunner serve` of the watched demo cell on the twin, a tote only its depth
camera sees standing on the path for 4 s: an independent Modbus client reads status bit
b10 OBSTRUCTED while the arm waits, a real headless Chromium shows the obstruction on the
status page, in words and in its live 3D view (the map's voxels, the one that stops the
arm), and the job finishes 0 once the tote is gone."""

from __future__ import annotations

import time

import pytest

from tests.web.browser import WEBGL_FLAGS, Chromium, chromium_path, keep_artifact
from tests.web.plc_page import (
    DONE,
    ERROR,
    JOB_ACK,
    OBSTRUCTED,
    READY,
    serving_the_tote,
)

HOST = "127.0.0.142"


@pytest.fixture
def serving(tmp_path):
    with serving_the_tote(tmp_path, HOST) as served:
        yield served


@pytest.mark.skipif(chromium_path() is None, reason="needs chromium")
def test_modbus_and_the_browser_show_the_arm_waiting_for_a_tote(serving, tmp_path):
    url, plc = serving
    with Chromium(url, flags=WEBGL_FLAGS) as page:
        plc.wait(READY, 60)
        plc.client.write_multiple_registers(2, [77, 1])
        plc.client.write_single_register(1, 1)  # JOB_REQ
        plc.wait(JOB_ACK, 10)
        obstructed_seen = shown = False
        drawn = None  # the live view's state while it shows the obstruction
        shot = False
        deadline = time.monotonic() + 120
        regs = None
        while time.monotonic() < deadline:
            regs = plc.poll()
            if regs and regs[1] & OBSTRUCTED:
                obstructed_seen = True
            if not shown and "Obstructed" in page.text("alarms"):
                shown = "occupied voxel at (" in page.text("alarms")
            if drawn is None and page.text("live-obstruction").startswith("Obstructed"):
                drawn = page.evaluate(
                    "(() => { const s = window.cellrunnerLive.state;"
                    " return {blocked: s.blocked, occupied: s.map && s.map.occupied}; })()"
                )
            if shown and drawn is not None and not shot:  # in words and in 3D: a picture
                keep_artifact(page.screenshot(tmp_path / "status_page_obstructed_3d.png"))
                shot = True
            if regs and regs[1] & (DONE | ERROR):
                break
            time.sleep(0.05)
        assert regs is not None and regs[1] & DONE and (regs[4], regs[5]) == (77, 0), regs
        assert not regs[1] & OBSTRUCTED
        plc.client.write_single_register(1, 0)
    assert obstructed_seen, "Modbus never showed OBSTRUCTED while the arm waited"
    assert shown, "the status page never showed the obstruction"
    # the 3D view drew the map and the voxel that stopped the arm, inside the tote
    assert drawn is not None and drawn["occupied"] > 0, drawn
    assert drawn["blocked"] is not None, drawn
    tote_min, tote_max = (0.42, -0.31, 1.05), (0.62, -0.17, 1.15)  # the tote, one voxel grown
    assert all(
        lo - 0.03 <= v <= hi + 0.03
        for v, lo, hi in zip(drawn["blocked"], tote_min, tote_max, strict=True)
    ), drawn
