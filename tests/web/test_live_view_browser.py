"""The live 3D cell of the status page, in a real headless Chromium (WebGL on SwiftShader),
on a real `cellrunner serve --backend sim --http` with a Modbus PLC running a pick and
place: the canvas draws the arm, the picture changes as the arm moves (and only then),
the mouse orbits and zooms, and the joint values the page shows are the backend's
(as /live/state.json serves them) within one update."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests.web.browser import WEBGL_FLAGS, Chromium, chromium_path, keep_artifact
from tests.web.live_rig import BACKGROUND, canvas_pixels, changed, get_json, shown
from tests.web.plc_page import DONE, ERROR, JOB_ACK, READY

pytestmark = pytest.mark.skipif(chromium_path() is None, reason="needs chromium")


def test_the_live_cell_draws_the_arm_and_follows_the_backend(live_serving, tmp_path):
    url, plc = live_serving
    scene = get_json(url + "live/scene.json", wait_s=30)
    assert [link["name"] for link in scene["links"]][:2] == ["base", "shoulder"]
    assert [f["name"] for f in scene["fixtures"]] == ["bench"]
    with Chromium(url, flags=WEBGL_FLAGS) as page:
        deadline = time.monotonic() + 60
        while not (
            page.evaluate("!!document.querySelector('#live3d canvas')")
            and shown(page)["seq"] > 0
            and page.text("state") == "Idle"
        ):
            plc.poll()
            assert time.monotonic() < deadline, (page.text("live-note"), page.text("state"))
            time.sleep(0.1)
        time.sleep(0.5)  # a few frames drawn
        idle = canvas_pixels(page, tmp_path / "idle_a.png")
        drawn = int((np.abs(idle - BACKGROUND).max(axis=2) > 24).sum())
        assert drawn > 0.02 * idle.shape[0] * idle.shape[1], drawn  # the arm, the bench
        plc.poll()
        time.sleep(0.3)
        # standing still, the picture stands still (a pixel's edge may flicker with the
        # servo's hundredths of a degree): what changes later is the arm moving
        still = changed(idle, canvas_pixels(page, tmp_path / "idle_b.png"))
        assert still <= 100, still
        q_home = shown(page)["q"]
        assert q_home == pytest.approx([0, -90, 90, -90, -90, 0], abs=0.05)

        plc.wait(READY, 30)
        plc.client.write_multiple_registers(2, [601, 1])
        plc.client.write_single_register(1, 1)  # JOB_REQ
        plc.wait(JOB_ACK, 5)
        compared, behind, moved_pixels, shot = 0, [], 0, None
        holding: set[str] = set()  # what the page says the gripper holds
        job = None
        deadline = time.monotonic() + 120
        regs = None
        while time.monotonic() < deadline:
            regs = plc.poll()
            before = get_json(url + "live/state.json")
            on_page = shown(page)
            after = get_json(url + "live/state.json")
            # how many updates the page is behind the sample served just before it was read
            behind.append(before["seq"] - on_page["seq"])
            assert on_page["seq"] <= after["seq"], (before, on_page, after)
            for served in (before, after):
                if served["seq"] == on_page["seq"]:
                    assert on_page["q"] == pytest.approx(served["q_deg"], abs=0.006)
                    compared += served["q_deg"] != pytest.approx(q_home, abs=1.0)
            if job is None and before["step"] >= 2:  # executing: its plan is ready
                job = get_json(url + "live/job.json")
                assert job["job_id"] == before["job_id"], job
            holding.add(page.text("live-carried"))
            if shot is None and before["step"] >= 5 and page.text("live-carried") == "can":
                shot = page.screenshot(tmp_path / "status_page_live3d.png")
                moved_pixels = changed(idle, canvas_pixels(page, tmp_path / "moving.png"))
            if regs and regs[1] & (DONE | ERROR):
                break
            time.sleep(0.05)
        assert regs is not None and regs[1] & DONE and (regs[4], regs[5]) == (601, 0), regs
        plc.client.write_single_register(1, 0)
        assert compared >= 5, (compared, behind)  # joints matched while the arm was away from home
        # within one update of the backend: the sample it served last before the read, or a
        # newer one; a read may find the browser's event loop busy drawing (WebGL in
        # software on a shared 2-core machine): never more than 0.25 s (5 updates) behind
        within_one = sum(b <= 1 for b in behind) / len(behind)
        assert within_one >= 0.9 and max(behind) <= 5, sorted(behind)
        # the arm moved in the picture: a good part of the view changed
        assert moved_pixels > 20 * max(still, 100), (moved_pixels, still)
        assert shot is not None, holding  # the can shown in the gripper while carried
        assert holding == {"nothing", "can"}, holding
        keep_artifact(shot)
        # the job's planned path, as the page fetched it: one polyline per motion of
        # TASK (home; approach, descend, lift at the pick; approach, descend, retreat at
        # the drop; home), none for the grip and the release
        assert job is not None and [seg["step"] for seg in job["path"]] == [1, 2, 3, 5, 6, 7, 9, 10]
        assert page.evaluate("window.cellrunnerLive.path.length") in (0, len(job["path"]))

        # the mouse orbits and zooms (the arm stands still at home again)
        time.sleep(0.5)
        rest = canvas_pixels(page, tmp_path / "rest.png")
        rect = page.evaluate(
            "(() => { const r = document.querySelector('#live3d canvas').getBoundingClientRect();"
            " return [r.x + r.width / 2, r.y + r.height / 2]; })()"
        )
        x, y = rect
        page.call(
            "Input.dispatchMouseEvent",
            type="mousePressed",
            x=x,
            y=y,
            button="left",
            buttons=1,
            clickCount=1,
        )
        for k in range(1, 11):
            page.call(
                "Input.dispatchMouseEvent",
                type="mouseMoved",
                x=x + 12 * k,
                y=y,
                button="left",
                buttons=1,
            )
        page.call(
            "Input.dispatchMouseEvent",
            type="mouseReleased",
            x=x + 120,
            y=y,
            button="left",
            buttons=1,
            clickCount=1,
        )
        time.sleep(0.3)
        orbited = canvas_pixels(page, tmp_path / "orbited.png")
        assert changed(rest, orbited) > 2000
        page.call("Input.dispatchMouseEvent", type="mouseWheel", x=x, y=y, deltaX=0, deltaY=-600)
        time.sleep(0.3)
        zoomed = canvas_pixels(page, tmp_path / "zoomed.png")
        assert changed(orbited, zoomed) > 2000
