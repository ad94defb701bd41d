"""SPEC section 8 over real sockets: the cell's OPC UA server, asyncua clients in processes."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user
from tests.plc.client_procs import run_clients
from tests.plc.conftest import HERE, PASSWORD, USER, plc_test_tasks
from tests.rig import free_port, write_client_cert


class Setup:
    def __init__(self, root: Path, cell: FakeCell, service: PlcService, url: str) -> None:
        self.root, self.cell, self.service, self.url = root, cell, service, url
        self.pki = root / "pki"
        self.trusted_cert, self.trusted_key = write_client_cert(root, "trusted-client")
        (self.pki / "trusted").mkdir(parents=True, exist_ok=True)
        (self.pki / "trusted" / "trusted-client.der").write_bytes(self.trusted_cert.read_bytes())
        self.stranger_cert, self.stranger_key = write_client_cert(root, "stranger")

    def args(self, **kw: Any) -> list[str]:
        opts = {
            "url": self.url,
            "scenario": "connect",
            "policy": "Basic256Sha256_SignAndEncrypt",
            "cert": str(self.trusted_cert),
            "key": str(self.trusted_key),
            "user": USER,
            "password": PASSWORD,
        }
        opts.update(kw)
        argv = [sys.executable, str(HERE / "opcua_client.py")]
        for key, value in opts.items():
            if value is not None:
                argv += [f"--{key}", str(value)]
        return argv


@pytest.fixture(scope="module")
def opcua(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Setup]:
    root = tmp_path_factory.mktemp("opcua")
    users = root / "secrets" / "opcua-users.yaml"
    add_user(users, USER, PASSWORD)
    add_user(users, "other", "another password")
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    cell = FakeCell(tasks=plc_test_tasks(), parts_processed=7).start()
    config = {"opcua": {"endpoint": url, "users": "secrets/opcua-users.yaml", "pki": "pki"}}
    service = PlcService(cell, config, base_dir=root)
    setup = Setup(root, cell, service, url)  # client certs trusted before the server starts
    service.start()
    try:
        yield setup
    finally:
        service.stop()
        cell.close()


def test_server_certificate_created_on_first_start(opcua: Setup) -> None:
    assert (opcua.pki / "own" / "cert.der").is_file()
    key = opcua.pki / "own" / "key.pem"
    assert key.is_file() and key.stat().st_mode & 0o077 == 0


def test_encrypted_user_session_runs_a_job_and_gets_the_completion_event(opcua: Setup) -> None:
    [out] = run_clients([opcua.args(scenario="job")])
    assert out["connected"], out
    assert out["types"] == {
        "State": "Int32",
        "StateName": "String",
        "Ready": "Boolean",
        "Busy": "Boolean",
        "ProtectiveStop": "Boolean",
        "EmergencyStop": "Boolean",
        "CurrentJobId": "String",
        "CurrentStep": "Int32",
        "ProdProcessed": "UInt32",
        "ProdDefective": "UInt32",
        "LastJob.JobId": "String",
        "LastJob.ResultCode": "Int32",
        "LastJob.ResultText": "String",
        "LastJob.CycleTime": "Double",
        "LastJob.EndTime": "DateTime",
        "LastJob.FailureKind": "String",
        "LastJob.FailureStep": "Int32",
    }
    job_id, code = out["first"]
    assert code == 0 and job_id
    assert out["start_latency_s"] < 1.0
    assert out["again"] == [job_id, 0]  # same ClientJobId: the first job, not a second
    assert out["again_after_end"] == [job_id, 0]
    assert out["events_cell"] == [{"JobId": job_id, "ResultCode": 0, "ClientJobId": "plc-job-1"}]
    assert out["events_server"] == out["events_cell"]
    assert out["last_job"] == {"JobId": job_id, "ResultCode": "0", "ResultText": "OK"}
    assert out["prod_processed"] == 8
    assert out["unknown_task"] == ["", 10]
    assert out["bad_params"] == ["", 11]
    assert out["bad_json"] == ["", 11]
    assert out["by_number"][1] == 0
    assert out["unhold_when_idle"] == "BadInvalidState"
    started = [r for r in opcua.cell.finished if r.client_job_id == "plc-job-1"]
    assert len(started) == 1 and started[0].source == "opcua"


def test_writes_to_cell_variables_are_refused(opcua: Setup) -> None:
    [out] = run_clients([opcua.args(scenario="write")])
    assert out["connected"], out
    refused = {"BadUserAccessDenied", "BadNotWritable", "BadWriteNotSupported"}
    assert out["State"] in refused and out["Ready"] in refused and out["LastJob.JobId"] in refused
    assert out["State_after"] != 6 or opcua.cell.status().state == 6


def test_security_negatives_are_all_refused(opcua: Setup) -> None:
    cases = {
        "anonymous": opcua.args(user=None, password=None),
        "wrong password": opcua.args(password="wrong"),
        "unknown user": opcua.args(user="mallory", password=PASSWORD),
        "untrusted cert": opcua.args(cert=str(opcua.stranger_cert), key=str(opcua.stranger_key)),
        "none security": opcua.args(policy="none", cert=None, key=None),
        "none security, forced": opcua.args(policy="none", cert=None, key=None) + ["--force"],
        "sign only, forced": opcua.args(policy="Basic256Sha256_Sign") + ["--force"],
        "admin without password": opcua.args(user="admin", password="x"),
        "sign only (not offered)": opcua.args(policy="Basic256Sha256_Sign"),
    }
    results = run_clients(list(cases.values()))
    for name, out in zip(cases, results, strict=True):
        assert not out["connected"], (name, out)
    rejected = list((opcua.pki / "rejected").iterdir())
    assert [p.name for p in rejected if p.name.startswith("stranger-")], rejected
    assert not any(p.name.startswith("trusted-client") for p in rejected)
    # the same credentials with a trusted certificate do work
    [ok] = run_clients([opcua.args()])
    assert ok["connected"] and isinstance(ok["state"], int), ok


def test_none_endpoint_only_when_written(tmp_path: Path) -> None:
    users = tmp_path / "users.yaml"
    add_user(users, USER, PASSWORD)
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    config = {
        "opcua": {
            "endpoint": url,
            "users": str(users),
            "security": ["none"],
            "pki": str(tmp_path / "pki"),
        }
    }
    with FakeCell(tasks=plc_test_tasks()) as cell, PlcService(cell, config):
        argv = [sys.executable, str(HERE / "opcua_client.py"), "--url", url, "--policy", "none"]
        ok, anonymous = run_clients([argv + ["--user", USER, "--password", PASSWORD], argv])
    assert ok["connected"], ok
    assert not anonymous["connected"], anonymous


def test_hostile_start_jobs_are_refused_cleanly(opcua: Setup) -> None:
    [out] = run_clients([opcua.args(scenario="hostile")])
    assert out["connected"], out
    for name in (
        "wrong_types",
        "null_parameters",
        "null_task",
        "null_client_job_id",
        "boolean_parameters",
        "thousand_digits",
        "thousand_digits_text",
        "infinity",
        "nan",
        "huge_number",
        "deep_json",
        "long_client_id",
        "long_task",
    ):
        assert out[name] == 11, (name, out[name])  # reject: bad params, no traceback, no job
    assert out["fine"] == 0
    assert not any(j.client_job_id.startswith("x") for j in opcua.cell.finished)


def test_register_server_without_a_session_is_refused(opcua: Setup) -> None:
    [out] = run_clients([[*opcua.args(scenario="register", policy="none")]])
    assert out.get("register") == "BadServiceUnsupported", out


def test_a_hold_over_opcua_is_published_as_held_by_opcua(opcua: Setup) -> None:
    [out] = run_clients([opcua.args(scenario="hold")])
    assert out["connected"], out
    assert out["job"][1] == 0, out
    assert (out["hold_source"], out["hold_reason"]) == ("opcua", "hold requested over OPC UA")
    assert opcua.cell.sources[opcua.cell.commands.index("hold")] == "opcua"
