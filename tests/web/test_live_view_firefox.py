"""The live 3D cell in a real Firefox (WebDriver BiDi; on a virtual X display, where
Mesa draws its WebGL), on a real `cellrunner serve --backend sim --http` running a job
from a Modbus PLC: the same page as in Chromium loads its three.js modules through the
import map, draws the arm, redraws it as it moves, and shows the backend's joints."""

from __future__ import annotations

import shutil
import time

import numpy as np
import pytest

from tests.web.browser import keep_artifact
from tests.web.firefox import Firefox, firefox_path, virtual_display
from tests.web.live_rig import BACKGROUND, changed, get_json, shown
from tests.web.plc_page import DONE, ERROR, JOB_ACK, READY

pytestmark = pytest.mark.skipif(
    firefox_path() is None or shutil.which("Xvfb") is None, reason="needs firefox and Xvfb"
)


def canvas_pixels(page: Firefox, path) -> np.ndarray:
    import cv2

    rect = page.evaluate(
        "(() => { const c = document.querySelector('#live3d canvas');"
        " c.scrollIntoView({block: 'center'}); const r = c.getBoundingClientRect();"
        " return {x: r.x, y: r.y, width: r.width, height: r.height}; })()"
    )
    page.screenshot(path, clip=rect)
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[0] > 100 and image.shape[1] > 100, rect
    return image[:, :, ::-1].astype(int)


def test_the_live_cell_in_firefox(live_serving, tmp_path):
    url, plc = live_serving
    get_json(url + "live/scene.json", wait_s=30)
    with virtual_display() as display, Firefox(url, display=display) as page:
        deadline = time.monotonic() + 60
        while not (
            page.evaluate("!!document.querySelector('#live3d canvas')") and shown(page)["seq"] > 0
        ):
            plc.poll()
            assert time.monotonic() < deadline, page.text("live-note")
            time.sleep(0.1)
        assert "WebGL" not in page.text("live-note")
        time.sleep(0.5)
        idle = canvas_pixels(page, tmp_path / "ff_idle.png")
        drawn = int((np.abs(idle - BACKGROUND).max(axis=2) > 24).sum())
        assert drawn > 0.02 * idle.shape[0] * idle.shape[1], drawn
        assert shown(page)["q"] == pytest.approx([0, -90, 90, -90, -90, 0], abs=0.05)

        plc.wait(READY, 30)
        plc.client.write_multiple_registers(2, [602, 1])
        plc.client.write_single_register(1, 1)  # JOB_REQ
        plc.wait(JOB_ACK, 5)
        compared, moved_pixels, regs = 0, 0, None
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            regs = plc.poll()
            before = get_json(url + "live/state.json")
            on_page = shown(page)
            after = get_json(url + "live/state.json")
            assert on_page["seq"] <= after["seq"]
            for served in (before, after):
                if served["seq"] == on_page["seq"]:
                    assert on_page["q"] == pytest.approx(served["q_deg"], abs=0.006)
                    compared += 1
            if not moved_pixels and before["step"] >= 5:
                moved_pixels = changed(idle, canvas_pixels(page, tmp_path / "ff_moving.png"))
                keep_artifact(page.screenshot(tmp_path / "status_page_live3d_firefox.png"))
            if regs and regs[1] & (DONE | ERROR):
                break
            time.sleep(0.05)
        assert regs is not None and regs[1] & DONE and (regs[4], regs[5]) == (602, 0), regs
        plc.client.write_single_register(1, 0)
        assert compared >= 5, compared
        assert moved_pixels > 2000, moved_pixels
