"""The live 3D view's test rig: a serve with its status page on the twin, and what the
browser drew and shows."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from tests.rig import CELL, TASK, free_port
from tests.web.browser import Chromium
from tests.web.plc_page import heartbeat, serve_with_page

HOST = "127.0.0.143"
#: the 3D view's background (page.html: #e8ebef)
BACKGROUND = np.array([0xE8, 0xEB, 0xEF])


@pytest.fixture
def live_serving(tmp_path):
    modbus_port, http_port = free_port(HOST), free_port(HOST)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        CELL + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {HOST}, port: {modbus_port}, "
        "heartbeat_timeout: 2.0}\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    with (
        serve_with_page(cell, HOST, modbus_port, http_port) as served,
        heartbeat(HOST, modbus_port),
    ):
        yield served


def get_json(url: str, wait_s: float = 0.0) -> dict:
    """The JSON at ``url``; retried for ``wait_s`` while nothing answers there (the
    status page comes up just after the PLC link)."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            with urllib.request.urlopen(url, timeout=5) as res:
                return json.load(res)
        except urllib.error.URLError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def canvas_pixels(page: Chromium, path: Path) -> np.ndarray:
    """The 3D view as the browser drew it (H x W x 3, RGB)."""
    import cv2

    rect = page.evaluate(
        "(() => { const r = document.querySelector('#live3d canvas').getBoundingClientRect();"
        " return {x: r.x + scrollX, y: r.y + scrollY, width: r.width, height: r.height}; })()"
    )
    page.screenshot(path, clip={**rect, "scale": 1})
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[0] > 100 and image.shape[1] > 100, rect
    return image[:, :, ::-1].astype(int)


def shown(page: Chromium) -> dict:
    """What the page shows of the arm: its sample number and the six joints (deg)."""
    return page.evaluate(
        "({seq: Number(document.getElementById('live-seq').textContent) || 0,"
        " q: [1,2,3,4,5,6].map(i => Number(document.getElementById('q' + i).textContent))})"
    )


def changed(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels that differ by more than a shade."""
    return int((np.abs(a - b).max(axis=2) > 24).sum())
