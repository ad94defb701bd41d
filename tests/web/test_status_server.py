"""The status page server over a real loopback socket, with the scripted FakeCell as
the engine and a real SQLite journal: JSON snapshot, Prometheus metrics (parsed with
prometheus_client's text-format parser), alarms with their fix, read-only routes."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

import pytest
from prometheus_client.parser import text_string_to_metric_families

from cellrunner.errors import UsageError
from cellrunner.execution.journal import Journal
from cellrunner.plc.fake import FakeCell
from cellrunner.web.board import StatusBoard
from cellrunner.web.server import StatusServer, is_loopback, parse_address

HOST = "127.0.0.140"


def get(url: str) -> tuple[int, str, str]:
    try:
        with urllib.request.urlopen(url, timeout=5) as res:
            return res.status, res.headers["Content-Type"], res.read().decode()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read().decode()


def metrics(url: str) -> dict[str, dict]:
    """{family name: {(sample name, frozen labels): value}}."""
    status, ctype, body = get(url + "metrics")
    assert status == 200 and ctype.startswith("text/plain; version=0.0.4")
    return {
        f.name: {(s.name, tuple(sorted(s.labels.items()))): s.value for s in f.samples}
        for f in text_string_to_metric_families(body)
    }


@pytest.fixture
def served(tmp_path):
    links = {"modbus": True}
    with FakeCell(results=[0, 1]) as cell:
        board = StatusBoard(
            cell,
            Journal(tmp_path / "jobs.sqlite"),
            "line3-cell2",
            plc_links=lambda: dict(links),
            max_age_s=0.0,
        ).setup()
        server = StatusServer(board, HOST, 0)
        server.start()
        try:
            yield cell, server.url, links
        finally:
            server.stop()
            board.close()


def wait_idle(cell: FakeCell, n_finished: int) -> None:
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        if len(cell.finished) >= n_finished and cell.status().ready:
            return
        time.sleep(0.01)
    raise AssertionError(f"fake cell did not finish {n_finished} jobs: {cell.status()}")


def test_snapshot_and_metrics_follow_the_jobs(served):
    cell, url, links = served
    status, ctype, body = get(url + "status.json")
    snap = json.loads(body)
    assert (status, ctype) == (200, "application/json")
    assert snap["cell"] == "line3-cell2" and snap["state"] == {"number": 4, "name": "Idle"}
    assert snap["job"] is None and snap["alarms"] == [] and snap["plc_links"] == {"modbus": True}
    m = metrics(url)
    assert (
        m["cellrunner_packml_state"][("cellrunner_packml_state", (("cell", "line3-cell2"),))] == 4
    )
    assert (
        m["cellrunner_jobs"][
            ("cellrunner_jobs_total", (("cell", "line3-cell2"), ("code", "0"), ("result", "OK")))
        ]
        == 0
    )
    assert (
        m["cellrunner_plc_link_up"][
            ("cellrunner_plc_link_up", (("cell", "line3-cell2"), ("link", "modbus")))
        ]
        == 1
    )

    for n in (1, 2):
        assert cell.start_job(1, {"slot": 3}, str(n), "modbus").accepted
        wait_idle(cell, n)
    links["modbus"] = False
    m = metrics(url)
    jobs = {dict(labels)["code"]: v for (_, labels), v in m["cellrunner_jobs"].items()}
    assert jobs == {"0": 1, "1": 1}
    hist = m["cellrunner_cycle_time_seconds"]
    assert hist[("cellrunner_cycle_time_seconds_count", (("cell", "line3-cell2"),))] == 2
    assert (
        hist[("cellrunner_cycle_time_seconds_bucket", (("cell", "line3-cell2"), ("le", "+Inf")))]
        == 2
    )
    assert (
        m["cellrunner_plc_link_up"][
            ("cellrunner_plc_link_up", (("cell", "line3-cell2"), ("link", "modbus")))
        ]
        == 0
    )

    alarms = json.loads(get(url + "status.json")[2])["alarms"]
    titles = [a["title"] for a in alarms]
    assert titles == ["PLC link down (modbus)", "Last job 1: no part (grip failed after retries)"]
    assert all(a["fix"] for a in alarms)


def test_estop_alarm_names_the_fix(served):
    cell, url, _ = served
    cell.inject_estop()
    snap = json.loads(get(url + "status.json")[2])
    assert snap["estop"] is True
    estop = snap["alarms"][0]
    assert estop["severity"] == "fault" and estop["title"] == "Emergency stop"
    assert "release the emergency stop, then Clear and Reset" in estop["fix"]
    m = metrics(url)
    assert m["cellrunner_estop"][("cellrunner_estop", (("cell", "line3-cell2"),))] == 1


def test_page_and_read_only_routes(served):
    _, url, _ = served
    status, ctype, body = get(url)
    assert status == 200 and ctype.startswith("text/html") and 'fetch("status.json"' in body
    assert get(url + "nope")[0] == 404
    req = urllib.request.Request(url + "status.json", data=b"{}", method="POST")
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(req, timeout=5)
    assert exc.value.code == 405


def test_address_parsing_defaults_to_loopback():
    assert parse_address("8080") == ("127.0.0.1", 8080)
    assert parse_address(":9000") == ("127.0.0.1", 9000)
    assert parse_address("0.0.0.0:8080") == ("0.0.0.0", 8080)
    assert parse_address("[::1]:8080") == ("::1", 8080)
    with pytest.raises(UsageError, match=r"--http 'localhost:http': give \[HOST:\]PORT"):
        parse_address("localhost:http")
    assert is_loopback("127.0.0.1") and is_loopback("::1") and not is_loopback("0.0.0.0")


def test_serve_refuses_a_bad_http_address_before_starting(capsys):
    from cellrunner.cli.main import main
    from tests.conftest import DEMO_CELL

    assert main(["serve", str(DEMO_CELL), "--http", "127.0.0.1:port"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "cellrunner serve: error: --http '127.0.0.1:port': give [HOST:]PORT with PORT 0-65535, "
        "e.g. 127.0.0.1:8080"
    ]


def test_plc_link_is_up_while_the_heartbeat_moves():
    """PlcService.links() over a real Modbus socket: down until the PLC heartbeat changes,
    up while it keeps changing, down again once it stops for heartbeat_timeout."""
    from pyModbusTCP.client import ModbusClient

    from cellrunner.plc.service import PlcService
    from tests.rig import free_port

    port = free_port(HOST)
    with (
        FakeCell() as cell,
        PlcService(
            cell, {"modbus": {"bind": HOST, "port": port, "heartbeat_timeout": 0.5}}
        ) as service,
    ):
        assert service.links() == {"modbus": False}
        client = ModbusClient(host=HOST, port=port, timeout=2.0, auto_open=True)
        for beat in range(1, 6):
            assert client.write_single_register(0, beat)
            time.sleep(0.05)
        assert service.links() == {"modbus": True}
        deadline = time.monotonic() + 3
        while service.links()["modbus"]:
            assert time.monotonic() < deadline, "the link stayed up without a heartbeat"
            time.sleep(0.05)
        client.close()
