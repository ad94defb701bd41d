"""The live 3D view's routes over a real loopback socket, fed by the real cell controller
on the MuJoCo twin in this process: each state is what the backend measured at that
sample's time, the server-sent events stream one state per sample and end when the server
stops, too many open views are refused, the vendored three.js is served as it is."""

from __future__ import annotations

import contextlib
import http.client
import io
import json
import signal
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from cellrunner.cli.common import load
from cellrunner.execution.journal import Journal
from cellrunner.planning.world import CellWorld
from cellrunner.web.board import StatusBoard
from cellrunner.web.live import LiveView
from cellrunner.web.live_feed import LiveFeed
from cellrunner.web.server import MAX_STREAMS, StatusServer
from tests.conftest import ROOT
from tests.execution.twin_cell import twin_cell
from tests.rig import CELL, TASK, write_cell

HOST = "127.0.0.144"


def get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as res:
            return res.status, res.headers["Content-Type"], res.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read()


def port_of(server: StatusServer) -> int:
    return int(server.url.rstrip("/").rsplit(":", 1)[1])


class Measured:
    """An observer of the control loop: what the backend measured, by its clock."""

    def __init__(self) -> None:
        self.q_by_time: dict[float, np.ndarray] = {}

    def __call__(self, cell) -> None:
        state = cell.backend.read_state()
        self.q_by_time[round(float(state.time_s), 4)] = np.array(state.q_rad)


@pytest.fixture
def served(tmp_path):
    cell_path, task_path = write_cell(tmp_path, CELL, TASK)
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(cell_path), str(task_path))
    controller, loop = twin_cell(cell, {1: task}, "sim")
    feed, measured = LiveFeed(rate_hz=50.0), Measured()
    loop.add_observer(feed)
    loop.add_observer(measured)
    board = StatusBoard(controller, Journal(tmp_path / "jobs.sqlite"), "dryrun-cell").setup()
    server = StatusServer(board, HOST, 0, LiveView(feed, CellWorld(cell)))
    server.start()
    stop = threading.Event()

    def control() -> None:  # the control thread: a job, then standing, for at most 60 s
        assert controller.start_job(1, {}, "1", "cli").accepted
        deadline = time.monotonic() + 60
        while not stop.is_set() and time.monotonic() < deadline:
            loop.step(5)
            time.sleep(0.002)

    thread = threading.Thread(target=control, daemon=True)
    thread.start()
    try:
        yield server, measured, feed
    finally:
        stop.set()
        thread.join(timeout=10)
        server.stop()
        board.close()
        controller.close()


def test_each_state_is_what_the_backend_measured_then(served):
    server, measured, _ = served
    seen: list[dict] = []
    deadline = time.monotonic() + 30
    while len({s["seq"] for s in seen}) < 10 or not any(s["step"] >= 3 for s in seen):
        assert time.monotonic() < deadline, seen[-1:] or "no state"
        status, ctype, body = get(server.url + "live/state.json")
        assert status == 200 and ctype == "application/json"
        state = json.loads(body)
        if state["seq"]:
            seen.append(state)
        time.sleep(0.03)
    seqs = [s["seq"] for s in seen]
    assert seqs == sorted(seqs)
    for state in seen:
        q = measured.q_by_time[state["time_s"]]
        assert state["q_deg"] == pytest.approx(np.degrees(q).tolist(), abs=1e-3)
        assert np.array(state["links"]).shape == (7, 16)
        assert state["tcp"] == pytest.approx(np.array(state["links"][6])[[3, 7, 11]], abs=0.3)
    moving = [s for s in seen if s["step"] >= 2]  # the arm away from home
    assert moving and any(s["q_deg"] != pytest.approx(seen[0]["q_deg"], abs=1.0) for s in moving), (
        moving
    )
    status, _, body = get(server.url + "live/job.json")
    job = json.loads(body)
    assert status == 200 and job["job_id"] in ("", moving[-1]["job_id"])


def test_the_stream_sends_each_sample_once_and_ends_with_the_server(served):
    server, _, _ = served
    connection = http.client.HTTPConnection(HOST, port_of(server), timeout=5)
    connection.request("GET", "/live/stream")
    response = connection.getresponse()
    assert response.status == 200 and response.headers["Content-Type"] == "text/event-stream"
    seqs: list[int] = []
    deadline = time.monotonic() + 20
    while len(seqs) < 15:
        assert time.monotonic() < deadline, seqs
        line = response.fp.readline()
        if line.startswith(b"data: "):
            seqs.append(json.loads(line[6:])["seq"])
    assert seqs == sorted(set(seqs))  # each sample once, in order
    assert seqs[-1] - seqs[0] < 2 * len(seqs)  # and hardly one missed (50 Hz)

    # more pages than MAX_STREAMS: the one too many is refused, the others stream on
    others = []
    for _ in range(MAX_STREAMS - 1):
        c = http.client.HTTPConnection(HOST, port_of(server), timeout=5)
        c.request("GET", "/live/stream")
        others.append((c, c.getresponse()))
    assert all(r.status == 200 for _, r in others)
    assert get(server.url + "live/stream")[0] == 503

    t0 = time.monotonic()
    server.stop()  # every stream ends, at once
    for r in [response, *(r for _, r in others)]:
        while r.fp.readline():
            assert time.monotonic() - t0 < 2.0
    assert time.monotonic() - t0 < 2.0
    connection.close()
    for c, _ in others:
        c.close()


def test_three_js_is_served_as_vendored_and_nothing_else_is(served):
    server, _, _ = served
    folder = ROOT / "cellrunner" / "web" / "static" / "three"
    for name in ("three.module.js", "three.core.js", "OrbitControls.js", "LICENSE"):
        status, ctype, body = get(server.url + "static/three/" + name)
        assert status == 200 and body == (folder / name).read_bytes()
        assert ctype.startswith("text/javascript" if name.endswith(".js") else "text/plain")
    assert get(server.url + "static/three/../server.py")[0] == 404
    assert get(server.url + "static/three/missing.js")[0] == 404
    assert get(server.url + "live/other.json")[0] == 404
    page = get(server.url)[2].decode()
    assert '"three": "./static/three/three.module.js"' in page
    assert 'id="live3d"' in page and 'id="q6"' in page


def test_without_a_live_view_there_are_no_live_routes(tmp_path):
    from cellrunner.plc.fake import FakeCell

    with FakeCell() as cell:
        board = StatusBoard(cell, Journal(tmp_path / "jobs.sqlite"), "c").setup()
        server = StatusServer(board, HOST, 0)
        server.start()
        try:
            for route in ("live/scene.json", "live/state.json", "live/stream"):
                assert get(server.url + route)[0] == 404
            assert get(server.url + "static/three/three.module.js")[0] == 404
        finally:
            server.stop()
            board.close()


def test_serve_ends_within_2_s_of_sigterm_with_five_live_views_open(tmp_path):
    from tests.rig import free_port, start_serve

    modbus_port, http_port = free_port(HOST), free_port(HOST)
    cell, _ = write_cell(
        tmp_path,
        CELL
        + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {HOST}, port: {modbus_port}}}\n",
        TASK,
    )
    proc = start_serve(cell, "--backend", "sim", "--http", f"{HOST}:{http_port}")
    url = f"http://{HOST}:{http_port}/"
    streams = []
    try:
        deadline = time.monotonic() + 90
        while get_status(url + "live/state.json") != 200:
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()[-2000:]
            time.sleep(0.2)
        for _ in range(5):
            stream = urllib.request.urlopen(url + "live/stream", timeout=5)
            streams.append(stream)
            assert stream.readline() == b"retry: 1000\n"
            while not stream.readline().startswith(b"data: "):
                pass
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        assert time.monotonic() - t0 < 2.0, err[-2000:]
        assert proc.returncode == 0, err[-2000:]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        for stream in streams:
            stream.close()


def get_status(url: str) -> int | None:
    try:
        return get(url)[0]
    except OSError:
        return None
