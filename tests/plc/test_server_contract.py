"""Every PLC server (:class:`cellrunner.plc.server.PlcServer`) over real sockets on
loopback: it starts under :class:`PlcService`, answers a real client of its protocol
(pymodbus, asyncua), says its link is up while that client is there, and stops within 2 s.
A new PLC protocol's server joins :data:`CASES`; the last test fails until it does."""

from __future__ import annotations

import asyncio
import importlib
import inspect
import pkgutil
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import cellrunner.plc
from cellrunner.plc.fake import FakeCell
from cellrunner.plc.modbus import ModbusServer
from cellrunner.plc.opcua import NAMESPACE_URI, OpcUaServer
from cellrunner.plc.server import PlcServer
from cellrunner.plc.service import PlcService
from cellrunner.plc.users import add_user
from tests.plc.conftest import PASSWORD, USER, plc_test_tasks
from tests.protocol_check import assert_implements
from tests.rig import free_port, write_client_cert

STOP_WITHIN_S = 2.0
#: a client's whole conversation with a server is bounded by this (s)
PEER_TIMEOUT_S = 20.0


@dataclass(frozen=True)
class Case:
    server_class: type
    #: (the directory for files) -> the ``plc`` section that turns this server on
    config: Callable[[Path], dict[str, Any]]
    #: talks to the running server as its peer, calling ``check_link`` while connected;
    #: what the server answered
    peer: Callable[[PlcService, Path, Callable[[], None]], Any]


def _modbus_config(root: Path) -> dict[str, Any]:
    return {"modbus": {"bind": "127.0.0.1", "port": 0, "heartbeat_timeout": 5.0}}


def _modbus_peer(service: PlcService, root: Path, check_link: Callable[[], None]) -> Any:
    from pymodbus.client import ModbusTcpClient

    assert service.modbus is not None
    host, port = service.modbus.address
    client = ModbusTcpClient(host, port=port, timeout=2, retries=0)
    assert client.connect()
    try:
        for beat in (1, 2, 3):  # the heartbeat moves: the link is up
            assert not client.write_register(0, beat).isError()
        rr = client.read_holding_registers(0, count=1)
        assert not rr.isError()
        check_link()
        return rr.registers
    finally:
        client.close()


def _opcua_config(root: Path) -> dict[str, Any]:
    add_user(root / "opcua-users.yaml", USER, PASSWORD)
    cert, _ = write_client_cert(root, "contract-client")
    (root / "pki" / "trusted").mkdir(parents=True, exist_ok=True)
    (root / "pki" / "trusted" / "contract-client.der").write_bytes(cert.read_bytes())
    url = f"opc.tcp://127.0.0.1:{free_port()}/cellrunner"
    return {"opcua": {"endpoint": url, "users": "opcua-users.yaml", "pki": "pki"}}


def _opcua_peer(service: PlcService, root: Path, check_link: Callable[[], None]) -> Any:
    async def talk() -> Any:
        from asyncua import Client, ua
        from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

        assert service.opcua is not None
        client = Client(service.opcua.endpoint, timeout=5)
        client.application_uri = "urn:cellrunner:test-client"
        await client.set_security(
            SecurityPolicyBasic256Sha256,
            str(root / "contract-client.der"),
            str(root / "contract-client.pem"),
            mode=ua.MessageSecurityMode.SignAndEncrypt,
        )
        client.set_user(USER)
        client.set_password(PASSWORD)
        async with client:
            idx = await client.get_namespace_index(NAMESPACE_URI)
            node = await client.nodes.objects.get_child([f"{idx}:Cell", f"{idx}:StateName"])
            answer = await node.read_value()
            check_link()
            return answer

    return asyncio.run(asyncio.wait_for(talk(), PEER_TIMEOUT_S))


CASES = {
    "modbus": Case(ModbusServer, _modbus_config, _modbus_peer),
    "opcua": Case(OpcUaServer, _opcua_config, _opcua_peer),
}


@pytest.fixture
def cell() -> Iterator[FakeCell]:
    fake = FakeCell(tasks=plc_test_tasks())
    with fake:
        yield fake


def _wait_for(predicate: Callable[[], bool], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    for _ in range(int(timeout_s / 0.02) + 1):  # bounded in count and in time
        if predicate() or time.monotonic() > deadline:
            break
        time.sleep(0.02)
    return predicate()


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_server_starts_answers_its_peer_and_stops_in_time(
    name: str, cell: FakeCell, tmp_path: Path
) -> None:
    case = CASES[name]
    service = PlcService(cell, case.config(tmp_path), base_dir=tmp_path)
    service.start(timeout_s=30.0)
    try:
        server = service._server(name)
        assert isinstance(server, case.server_class)
        assert isinstance(server, PlcServer)
        assert_implements(server, PlcServer)
        assert server.name == name
        assert server.published_at
        assert service.links() == {name: False}  # no peer yet

        def check_link() -> None:
            assert _wait_for(lambda: server.link_up, 5.0), f"{name}: the link is not up"
            assert service.links() == {name: True}

        answer = case.peer(service, tmp_path, check_link)
        assert answer is not None
    finally:
        t0 = time.monotonic()
        service.stop(timeout_s=STOP_WITHIN_S)
        took_s = time.monotonic() - t0
    assert took_s < STOP_WITHIN_S, f"{name} took {took_s:.2f} s to stop"
    assert service._threads == []


def _plc_server_classes() -> set[type]:
    """Every class in cellrunner.plc that has the Protocol's members."""
    members = ("name", "link_up", "published_at", "start", "stop")
    found = set()
    for info in pkgutil.iter_modules(cellrunner.plc.__path__):
        module = importlib.import_module(f"cellrunner.plc.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            mine = cls.__module__ == module.__name__ and cls is not PlcServer
            if mine and all(hasattr(cls, m) for m in members):
                found.add(cls)
    return found


def test_every_plc_server_has_a_contract_case() -> None:
    classes = _plc_server_classes()
    assert classes >= {ModbusServer, OpcUaServer}
    assert classes == {case.server_class for case in CASES.values()}
