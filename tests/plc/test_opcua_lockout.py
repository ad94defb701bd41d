"""The real PLC cannot be locked out of OPC UA (issue 28): not by connections that never
log in filling the cap, not by a wrong-password flood from another trusted client; and a
refusal for rate says so (BadTooManyOperations), not BadUserAccessDenied.

The server runs here (PlcService over a FakeCell, Basic256Sha256 SignAndEncrypt); the
PLC, the flood and the idle connections are processes of their own (asyncua's Client,
raw sockets)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.opcua import MAX_CONNECTIONS
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user
from tests.plc.conftest import HERE, PASSWORD, USER, child_env, plc_test_tasks
from tests.rig import free_port, write_client_cert

POLICY = "Basic256Sha256_SignAndEncrypt"

HOLD_CONNECTIONS = """
import socket, sys, time
host, port, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
socks = [socket.create_connection((host, port), timeout=5) for _ in range(n)]
print("open", flush=True)
sys.stdin.read()  # hold them until told
"""


class Server:
    def __init__(self, root: Path) -> None:
        self.root = root
        add_user(root / "users.yaml", USER, PASSWORD)
        self.url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
        trusted = root / "pki" / "trusted"
        trusted.mkdir(parents=True)
        self.certs: dict[str, tuple[Path, Path]] = {}
        for name in ("plc", "flood"):
            cert, key = write_client_cert(root, name)
            (trusted / f"{name}.der").write_bytes(cert.read_bytes())
            self.certs[name] = (cert, key)
        self.cell = FakeCell(tasks=plc_test_tasks()).start()
        config = {"opcua": {"endpoint": self.url, "users": "users.yaml", "pki": "pki"}}
        self.service = PlcService(self.cell, config, base_dir=root)

    def plc_login(self, timeout_s: float = 30) -> dict[str, Any]:
        cert, key = self.certs["plc"]
        argv = [sys.executable, str(HERE / "opcua_client.py"), "--url", self.url]
        argv += ["--scenario", "connect", "--policy", POLICY, "--cert", str(cert)]
        argv += ["--key", str(key), "--user", USER, "--password", PASSWORD]
        argv += ["--timeout", "15"]  # slow on a loaded machine is not locked out
        t0 = time.monotonic()
        out = subprocess.run(
            argv, capture_output=True, text=True, timeout=timeout_s, env=child_env()
        )
        lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
        result = json.loads(lines[-1]) if lines else {"connected": False, "error": out.stderr}
        result["seconds"] = round(time.monotonic() - t0, 2)
        return result

    def flood(self, logins: int, concurrency: int) -> subprocess.Popen[str]:
        cert, key = self.certs["flood"]
        argv = [sys.executable, str(HERE / "opcua_flood.py"), "--url", self.url]
        argv += ["--user", USER, "--logins", str(logins), "--concurrency", str(concurrency)]
        argv += ["--policy", POLICY, "--cert", str(cert), "--key", str(key)]
        return subprocess.Popen(argv, stdout=subprocess.PIPE, text=True, env=child_env())


@pytest.fixture
def server(tmp_path: Path) -> Iterator[Server]:
    setup = Server(tmp_path)
    setup.service.start()
    try:
        yield setup
    finally:
        setup.service.stop()
        setup.cell.close()


def test_connections_that_never_log_in_do_not_keep_the_plc_out(server: Server) -> None:
    host, port = server.url.split("//")[1].split("/")[0].split(":")
    idle = subprocess.Popen(
        [sys.executable, "-c", HOLD_CONNECTIONS, host, port, str(MAX_CONNECTIONS + 8)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert idle.stdout is not None and idle.stdout.readline().strip() == "open"
        tries = [server.plc_login() for _ in range(3)]
    finally:
        idle.communicate("", timeout=10)
    assert all(t["connected"] for t in tries), tries  # 3 of 3, each well inside the grace
    assert max(t["seconds"] for t in tries) < 10, tries


def test_a_flood_from_another_trusted_client_never_locks_the_plc_out(server: Server) -> None:
    floods = [server.flood(logins=100, concurrency=40)]
    try:
        time.sleep(1.0)  # under way (it lasts well beyond the PLC's five logins)
        tries = [server.plc_login() for _ in range(5)]
    finally:
        results = [
            json.loads(f.communicate(timeout=120)[0].strip().splitlines()[-1]) for f in floods
        ]
    assert all(t["connected"] for t in tries), (tries, results)  # 5 of 5
    statuses: dict[str, int] = {}
    for result in results:
        assert result["accepted"] == 0, result
        for name, n in result["statuses"].items():
            statuses[name] = statuses.get(name, 0) + n
    # refused for rate with the status that says so; the wrong passwords it did check
    assert statuses.get("BadTooManyOperations", 0) > 0, statuses
    assert statuses.get("BadUserAccessDenied", 0) > 0, statuses
