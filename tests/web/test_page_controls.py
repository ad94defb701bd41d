"""Holds say who held (issue 37): an operator presses Hold on the status page, through the
real HTTP server on loopback with the credentials of the cell's users file, and the log,
the journal, the page (status.json and its alarm) and OPC UA (a real asyncua client in
its own process) all say the page held the cell; Resume and Clear; who may press."""

from __future__ import annotations

import base64
import json
import sys
import threading
import time
import urllib.error
import urllib.request

import pytest

from cellrunner.execution.journal import Journal
from cellrunner.model.codes import PackMLState as S
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user, role_checker
from cellrunner.web.board import StatusBoard
from cellrunner.web.controls import HEADER, PageControls
from cellrunner.web.server import StatusServer
from tests.execution.fakes import ScriptedArm, tick
from tests.execution.held import held_cell
from tests.plc.client_procs import run_clients
from tests.plc.conftest import HERE
from tests.rig import free_port

HOST = "127.0.0.146"
REASON = "hold requested on the status page"


def press(url: str, button: str, user: str | None, password: str = "", marked: bool = True):
    """POST /control/BUTTON: (HTTP status, the JSON answer, headers)."""
    headers = {HEADER: "1"} if marked else {}
    if user is not None:
        token = base64.b64encode(f"{user}:{password}".encode()).decode()
        headers["Authorization"] = f"Basic {token}"
    req = urllib.request.Request(url + "control/" + button, data=b"", headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as res:
            return res.status, json.loads(res.read()), res.headers
    except urllib.error.HTTPError as exc:
        body = exc.read()
        is_json = exc.headers["Content-Type"] == "application/json"
        return exc.code, json.loads(body) if is_json else body.decode(), exc.headers


def snapshot(url: str) -> dict:
    with urllib.request.urlopen(url + "status.json", timeout=5) as res:
        return json.loads(res.read())


@pytest.fixture
def page(tmp_path):
    """The demo cell with a job under way, ticked by its own thread; its status page with
    the buttons for the users file's operators; its OPC UA server (security none, users)."""
    users = tmp_path / "users.yaml"
    add_user(users, "anna", "night shift 3")
    add_user(users, "mes", "dashboard only", role="viewer")
    cell, log, job_id = held_cell(tmp_path, ScriptedArm())
    stop = threading.Event()

    def control_loop() -> None:  # the control thread: bounded in time
        deadline = time.monotonic() + 120
        while not stop.is_set() and time.monotonic() < deadline:
            tick(cell)
            time.sleep(0.0005)

    ticker = threading.Thread(target=control_loop, daemon=True)
    ticker.start()
    board = StatusBoard(cell, Journal(tmp_path / "jobs.sqlite"), "demo", max_age_s=0.0).setup()
    server = StatusServer(board, HOST, 0, controls=PageControls(cell, role_checker(users), log))
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    opcua = {"endpoint": url, "users": str(users), "security": ["none"]}
    service = PlcService(cell, {"opcua": {**opcua, "pki": str(tmp_path / "pki")}})
    server.start()
    service.start()
    try:
        yield cell, log, job_id, server.url, url
    finally:
        service.stop()
        server.stop()
        board.close()
        stop.set()
        ticker.join(5)
        cell.close()


def wait_state(cell, state, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cell.status().state == state:
            return
        time.sleep(0.01)
    raise AssertionError(f"not {state.name}: {cell.status().state_name}")


def test_an_operator_holds_on_the_page_and_log_journal_page_and_opcua_say_so(page):
    cell, log, job_id, url, opcua_url = page
    wait_state(cell, S.EXECUTE)
    assert snapshot(url)["controls"] is True
    # who may press: nobody unnamed, no viewer, no page of another site (no header)
    status, answer, headers = press(url, "hold", None)
    assert status == 401 and headers["WWW-Authenticate"].startswith("Basic")
    assert press(url, "hold", "anna", "wrong")[0] == 401
    status, answer, _ = press(url, "hold", "mes", "dashboard only")
    assert status == 403 and "viewer" in answer["message"]
    assert press(url, "hold", "anna", "night shift 3", marked=False)[0] == 403
    assert press(url, "halt", "anna", "night shift 3")[0] == 404
    assert cell.status().state == S.EXECUTE  # none of those held the cell
    # the operator's Hold
    status, answer, _ = press(url, "hold", "anna", "night shift 3")
    assert (status, answer) == (200, {"ok": True, "message": "hold by anna"})
    wait_state(cell, S.HELD)
    # the page
    snap = snapshot(url)
    held = [a for a in snap["alarms"] if "held" in a["detail"]]
    assert held and held[0]["detail"] == f"The running job is held by page: {REASON}."
    # the log: the hold with its source, and the press with its user
    holds = [fields for event, fields in log.events if event == "hold"]
    assert [(h["source"], h["reason"]) for h in holds] == [("page", REASON)]
    presses = [fields for event, fields in log.events if event == "page_command"]
    assert presses == [{"command": "hold", "user": "anna", "accepted": True}]
    # the journal
    held_rows = [row for row in cell.journal.steps_of(job_id) if row[3] == "held"]
    assert [row[-1] for row in held_rows] == [f"page: {REASON}"]
    # OPC UA, read by a client of its own
    argv = [sys.executable, str(HERE / "opcua_client.py"), "--url", opcua_url, "--policy", "none"]
    [out] = run_clients(
        [argv + ["--user", "mes", "--password", "dashboard only", "--scenario", "held"]]
    )
    assert out["connected"], out
    assert (out["hold_source"], out["hold_reason"]) == ("page", REASON)
    # Clear is not for a held job (409, the state named); Resume is
    status, answer, _ = press(url, "clear", "anna", "night shift 3")
    assert status == 409 and "Held" in answer["message"]
    assert press(url, "unhold", "anna", "night shift 3")[0] == 200
    wait_state(cell, S.EXECUTE)
    assert cell.status().hold_source == ""


def test_without_a_users_file_the_page_stays_read_only(tmp_path):
    cell, _, _ = held_cell(tmp_path, ScriptedArm())
    board = StatusBoard(cell, Journal(tmp_path / "jobs.sqlite"), "demo", max_age_s=0.0).setup()
    server = StatusServer(board, HOST, 0)
    server.start()
    try:
        assert snapshot(server.url)["controls"] is False
        status, answer, _ = press(server.url, "hold", "anna", "night shift 3")
        assert status == 405 and "read-only" in answer
    finally:
        server.stop()
        board.close()
        cell.close()
    assert cell.status().hold_source == ""
