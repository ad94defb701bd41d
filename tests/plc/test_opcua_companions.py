"""SPEC 13, the plant's language, over real sockets: a generic asyncua client in its own
process (tests/plc/companion_client.py), which knows only the standards' namespace URIs
and BrowseNames, against the cell's OPC UA server (Basic256Sha256 SignAndEncrypt, a
trusted client certificate, users from the users file)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cellrunner.errors import InputError
from cellrunner.plc.fake import FakeCell
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user, load_user_entries
from tests.plc.client_procs import run_clients
from tests.plc.conftest import HERE, PASSWORD, USER, plc_test_tasks
from tests.rig import free_port, write_client_cert

VIEWER, VIEWER_PASSWORD = "mes-dashboard", "only looking"


class Plant:
    def __init__(self, root: Path, cell: FakeCell, url: str) -> None:
        self.root, self.cell, self.url = root, cell, url
        self.cert, self.key = write_client_cert(root, "mes")
        (root / "pki" / "trusted").mkdir(parents=True, exist_ok=True)
        (root / "pki" / "trusted" / "mes.der").write_bytes(self.cert.read_bytes())
        self.service: PlcService | None = None

    def restart(self) -> None:
        """A new OPC UA server (a restart of serve) on the same cell and journal."""
        if self.service is not None:
            self.service.stop()
        config = {"opcua": {"endpoint": self.url, "users": "users.yaml", "pki": "pki"}}
        self.service = PlcService(self.cell, config, base_dir=self.root, cell_name="line3")
        self.service.start()

    def client(
        self, scenario: str, *, user: str = USER, password: str = PASSWORD, **kw: Any
    ) -> dict[str, Any]:
        import sys

        argv = [
            sys.executable, str(HERE / "companion_client.py"), "--url", self.url,
            "--scenario", scenario, "--cert", str(self.cert), "--key", str(self.key),
            "--user", user, "--password", password,
        ]  # fmt: skip
        for key, value in kw.items():
            argv += [f"--{key}"] if value is True else [f"--{key}", str(value)]
        [out] = run_clients([argv], timeout_s=120)
        assert out.get("connected") and "error" not in out, out
        return out


@pytest.fixture(scope="module")
def plant(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Plant]:
    root = tmp_path_factory.mktemp("plant")
    users = root / "users.yaml"
    add_user(users, USER, PASSWORD)
    add_user(users, VIEWER, VIEWER_PASSWORD, "viewer")
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    cell = FakeCell(tasks=plc_test_tasks(), parts_processed=7).start()
    plant = Plant(root, cell, url)
    plant.restart()
    try:
        yield plant
    finally:
        assert plant.service is not None
        plant.service.stop()
        cell.close()


def test_a_generic_client_finds_the_arm_its_axes_and_the_packml_state(plant: Plant) -> None:
    out = plant.client("browse")
    robot, packml = out["robotics"], out["packml"]
    assert out["entry_points"] == {
        "Machines": ["BaseObjectType"],  # the cell
        "DeviceSet": ["MotionDeviceSystemType"],
    }
    assert robot["model"] == "UR5e" and robot["serial"] == "20235500042"
    assert {"Manufacturer", "Model", "SerialNumber", "Axes", "ParameterSet"} <= set(
        robot["arm_type_members"]
    )  # the type declares what its instances show
    assert robot["axes"] == ["Base", "Shoulder", "Elbow", "Wrist1", "Wrist2", "Wrist3"]
    for row in robot["positions"]:  # degrees, as OPC 40010 gives rotary axes
        assert [round(p) for p, _ in row] == [0, -90, 90, -90, -90, 0]
        assert all(speed == 0.0 for _, speed in row)
    assert robot["task_program"] == "" and robot["EmergencyStop"] is False
    assert packml["states"] == [["Cleared", 19], ["Running", 18], ["Idle", 4]]
    assert packml["ProdProcessedCount"] == [7] and packml["ProdDefectiveCount"] == [0]
    assert packml["UnitModeCurrent"] == 1
    assert packml["StopReason"] == [0, ""]


def test_a_job_order_runs_once_and_answers_by_id_and_by_state(plant: Plant) -> None:
    before = len(plant.cell.finished)
    out = plant.client("orders", task="slow", order="MES-7", cell=True)
    assert out["store_and_start"] == 1  # ReturnStatus bit 0: no error
    first = out["first"]
    assert first["states"] == [5, 1] and first["state_names"] == ["Ended", "Completed"]
    assert first["data"]["ResultCode"] == 0 and first["data"]["Task"] == "slow"
    assert first["data"]["CycleTime"] > 1.0  # three steps of 0.4 s
    job_id = first["data"]["JobId"]
    assert "slow" in out["task_programs"]  # TaskControl named the running task
    assert max(out["base_positions"]) > 5  # degrees: the axis moved while the job ran
    # the same order again is the same job
    assert out["again"] == 1 and out["again_response"]["data"]["JobId"] == job_id
    ran = [r for r in plant.cell.finished[before:] if r.client_job_id == "MES-7"]
    assert [(r.job_id, r.source) for r in ran] == [(job_id, "opcua")]
    assert out["cell_last_job"] == job_id  # Cell (SPEC 8) saw the same job
    # stored, aborted before it started, then cleared
    assert out["store"] == 1 and out["stored"]["states"] == [1, 2]
    assert out["abort"] == 1 and out["aborted"]["states"] == [6]
    assert out["start_aborted"] == 8  # invalid job order status
    assert out["clear"] == 1 and out["unknown"] == 2  # unknown job order id
    assert "MES-7" in out["ended_orders"] and "MES-7-b" not in out["ended_orders"]
    assert ["MES-7", [5, 1]] in out["list"]
    assert out["work_masters"] == [["pick_place", ["slot", "depth"]], ["home", []], ["slow", []]]
    assert all(order != "MES-7-b" for order, _ in out["list"])
    events = out["events"]
    assert events.index(["MES-7", [3]]) < events.index(["MES-7", [5, 1]])
    assert ["MES-7-b", [1, 2]] in events and ["MES-7-b", [6]] in events
    assert not [r for r in plant.cell.finished[before:] if r.client_job_id == "MES-7-b"]


def test_a_running_order_aborted_ends_aborted_with_the_cells_result(plant: Plant) -> None:
    out = plant.client("abort", task="slow", order="MES-A")
    assert out["store_and_start"] == 1 and out["abort"] == 1
    assert 3 in out["seen"] and out["ended"]["states"] == [6]  # Running, then Aborted
    assert out["ended"]["data"]["ResultCode"] == 106  # aborted by the PLC (SPEC 7)
    assert out["abort_again"] == 8  # an aborted order: invalid status
    [job] = [r for r in plant.cell.finished if r.client_job_id == "MES-A"]
    assert job.result_code == 106
    for command in ("clear", "reset"):  # the cell back to Idle for the next tests
        deadline = time.monotonic() + 5
        while not plant.cell.command(command):
            assert time.monotonic() < deadline, plant.cell.status()
            time.sleep(0.05)
    deadline = time.monotonic() + 5
    while not plant.cell.status().ready:
        assert time.monotonic() < deadline, plant.cell.status()
        time.sleep(0.05)


def test_after_a_restart_an_order_is_answered_from_the_journal_and_not_run_again(
    plant: Plant,
) -> None:
    before = plant.client("orders", task="home", order="MES-R")
    plant.restart()
    after = plant.client("orders", task="home", order="MES-R")
    assert after["store_and_start"] == 1 and after["first"]["states"] == [5, 1]
    assert after["first"]["data"] == before["first"]["data"]  # the same job, its response
    assert ["MES-R", [5, 1]] in after["list"]
    assert len([r for r in plant.cell.finished if r.client_job_id == "MES-R"]) == 1


def test_a_viewer_reads_everything_and_starts_holds_aborts_nothing(plant: Plant) -> None:
    commands, finished = list(plant.cell.commands), len(plant.cell.finished)
    out = plant.client("viewer", user=VIEWER, password=VIEWER_PASSWORD, order="V-1")
    refused = "BadUserAccessDenied"
    assert out["store_and_start"] == out["abort"] == refused
    assert out["cell_start_job"] == out["cell_hold"] == refused
    assert out["response_by_id"] == "called"  # reading a response is reading
    assert out["packml"]["states"][0] == ["Cleared", 19]
    assert plant.cell.commands == commands and len(plant.cell.finished) == finished


def test_roles_are_written_and_read_back(tmp_path: Path) -> None:
    users = tmp_path / "users.yaml"
    add_user(users, "plc1", "pw")
    add_user(users, "dash", "pw", "viewer")
    entries = load_user_entries(users)
    assert {name: e.role for name, e in entries.items()} == {"plc1": "operator", "dash": "viewer"}
    assert "'plc1': 'scrypt$" in users.read_text()  # an operator's line as before roles


def test_the_example_client_of_the_plc_interface_page_runs_a_job_order(
    plant: Plant, tmp_path: Path
) -> None:
    import subprocess
    import sys

    from tests.plc.conftest import REPO, child_env

    page = (REPO / "docs" / "plc-interface.md").read_text()
    start = page.index("```python", page.index("An example client")) + len("```python")
    script = tmp_path / "mes_client.py"
    script.write_text(page[start : page.index("```", start)])
    run = subprocess.run(
        [sys.executable, str(script), plant.url, str(plant.cert), str(plant.key),
         USER, PASSWORD, "home", "DOC-1"],
        capture_output=True, text=True, timeout=120, env=child_env(),
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.splitlines() == ["StoreAndStart: accepted", "Completed result 0"]
    [job] = [r for r in plant.cell.finished if r.client_job_id == "DOC-1"]
    assert job.task == "home" and job.result_code == 0


def test_users_add_takes_a_role_and_refuses_an_unknown_one(tmp_path: Path) -> None:
    from tests.rig import cli

    users = tmp_path / "users.yaml"
    made = cli("users", "add", str(users), "dash", "--role", "viewer", "--password-stdin",
               input="pw\n", timeout_s=60)  # fmt: skip
    assert made.returncode == 0, made.stderr
    assert load_user_entries(users)["dash"].role == "viewer"
    refused = cli("users", "add", str(users), "x", "--role", "admin", "--password-stdin",
                  input="pw\n", timeout_s=60)  # fmt: skip
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "admin" in refused.stderr and "x" not in load_user_entries(users)
    users.write_text("'dash': {hash: 'scrypt$1$1$1$AA==$AA==', role: root}\n")
    with pytest.raises(InputError) as err:
        load_user_entries(users)
    assert err.value.diagnostics[0].message == (
        "user 'dash': role 'root' is not one of operator, viewer"
    )
