"""The status page of a real `cellrunner serve` (twin backend, Modbus PLC link) in a real
headless Chromium: the page follows a running job's steps live, shows the result after
it, and /metrics parses with Prometheus' text-format parser."""

from __future__ import annotations

import time
import urllib.request

import pytest
from prometheus_client.parser import text_string_to_metric_families

from tests.rig import CELL, TASK, free_port
from tests.web.browser import Chromium, keep_artifact
from tests.web.plc_page import DONE, ERROR, JOB_ACK, READY, serve_with_page

HOST = "127.0.0.141"


@pytest.fixture
def serving(tmp_path):
    modbus_port, http_port = free_port(HOST), free_port(HOST)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        CELL + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {HOST}, port: {modbus_port}, "
        "heartbeat_timeout: 2.0}\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    with serve_with_page(cell, HOST, modbus_port, http_port) as served:
        yield served


def test_page_follows_a_running_job_in_chromium(serving, tmp_path):
    url, plc = serving
    with Chromium(url) as page:
        deadline = time.monotonic() + 30
        while page.text("state") != "Idle" or "PLC modbus up" not in page.text("links"):
            plc.poll()  # the heartbeat moving is what brings the link up
            assert time.monotonic() < deadline, (
                f"page shows {page.text('state')!r}, {page.text('links')!r}"
            )
            time.sleep(0.1)
        assert page.text("cell") == "dryrun-cell"

        plc.wait(READY, 30)
        plc.client.write_multiple_registers(2, [501, 1])
        plc.client.write_single_register(1, 1)  # JOB_REQ
        plc.wait(JOB_ACK, 5)
        seen: list[str] = []  # the step line as the browser shows it, each change once
        shot = None
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            regs = plc.poll()
            step = page.text("step")
            if step.startswith("step ") and (not seen or seen[-1] != step):
                seen.append(step)
                if len(seen) == 4:
                    shot = page.screenshot(tmp_path / "status_page_running.png")
                    assert page.text("state") == "Execute"
            if regs and regs[1] & (DONE | ERROR):
                break
            time.sleep(0.1)
        assert regs[1] & DONE and (regs[4], regs[5]) == (501, 0), regs
        plc.client.write_single_register(1, 0)
        # a live page: the step line moved forward through the job, step by step
        assert len(seen) >= 4, seen
        indices = [int(s.split(":")[0].split()[1]) for s in seen]
        assert indices == sorted(indices) and indices[0] <= 2 and indices[-1] >= 9, seen
        assert len({s.rsplit("(", 1)[1] for s in seen}) >= 3, seen  # several kinds of step shown
        assert shot is not None and shot.stat().st_size > 10_000
        keep_artifact(shot)

        deadline = time.monotonic() + 15
        while "501" not in page.text("results") or page.text("state") != "Idle":
            plc.poll()
            assert time.monotonic() < deadline, page.text("results")
            time.sleep(0.1)
        row = page.evaluate(
            "[...document.querySelectorAll('#results tr:first-child td')].map(td => td.textContent)"
        )
        assert row[2:5] == ["modbus 501", "move_can", ""] and row[5] == "0", row
        assert page.evaluate("document.querySelectorAll('#trend svg rect').length") == 1
        keep_artifact(page.screenshot(tmp_path / "status_page_done.png"))

    with urllib.request.urlopen(url + "metrics", timeout=5) as res:
        families = {f.name: f for f in text_string_to_metric_families(res.read().decode())}
    jobs = {s.labels["code"]: s.value for s in families["cellrunner_jobs"].samples}
    assert jobs["0"] == 1
    count = [
        s.value
        for s in families["cellrunner_cycle_time_seconds"].samples
        if s.name.endswith("_count")
    ]
    assert count == [1]
    assert [s.value for s in families["cellrunner_plc_link_up"].samples] == [1]
    assert families["cellrunner_parts_processed"].samples[0].value == 1


def test_alarms_show_their_fix_in_chromium(tmp_path):
    """An e-stop after a NOK job, the PLC link down: each alarm with its fix, drawn by the browser."""
    from cellrunner.execution.journal import Journal
    from cellrunner.plc.fake import FakeCell
    from cellrunner.web.board import StatusBoard
    from cellrunner.web.server import StatusServer

    with FakeCell(results=[1]) as cell:
        board = StatusBoard(
            cell,
            Journal(tmp_path / "jobs.sqlite"),
            "line3-cell2",
            plc_links=lambda: {"modbus": False},
        ).setup()
        server = StatusServer(board, HOST, 0)
        server.start()
        try:
            assert cell.start_job(1, {"slot": 2}, "9", "modbus").accepted
            deadline = time.monotonic() + 5
            while not cell.finished:
                assert time.monotonic() < deadline
                time.sleep(0.01)
            cell.inject_estop()
            with Chromium(server.url) as page:
                deadline = time.monotonic() + 15
                while (
                    page.evaluate(
                        "document.querySelectorAll('#alarms li.fault, #alarms li.warning').length"
                    )
                    < 3
                ):
                    assert time.monotonic() < deadline, page.text("alarms")
                    time.sleep(0.1)
                titles = page.evaluate(
                    "[...document.querySelectorAll('#alarms .title')].map(e => e.textContent)"
                )
                assert titles == [
                    "Emergency stop",
                    "PLC link down (modbus)",
                    "Last job 1: no part (grip failed after retries)",
                ], titles
                fixes = page.evaluate(
                    "[...document.querySelectorAll('#alarms .fix')].map(e => e.textContent)"
                )
                assert len(fixes) == 3 and "release the emergency stop" in fixes[0], fixes
                assert "a part is at the pick frame" in fixes[2], fixes
                assert "PLC modbus down" in page.text("links")
                keep_artifact(page.screenshot(tmp_path / "status_page_alarms.png"))
        finally:
            server.stop()
            board.close()
