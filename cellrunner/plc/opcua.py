"""OPC UA server: SPEC section 8 (asyncua, imported lazily).

Address space (namespace ``urn:cellrunner``)::

    Objects/Cell                       EventNotifier: JobCompletedEventType
      State Int32, StateName String, Ready/Busy/ProtectiveStop/EmergencyStop Boolean,
      CurrentJobId String, CurrentStep Int32, ProdProcessed/ProdDefective UInt32
      LastJob/  JobId String, ResultCode Int32, ResultText String, CycleTime Double (s),
                EndTime DateTime
      StartJob(TaskName, Parameters JSON, ClientJobId) -> (JobId, ReturnCode)
      Reset() Hold() Unhold() Abort() Clear() Stop()

Beside ``Cell``, the same cell in the plant's language (SPEC 13): ISA-95 job orders, PackML
and OPC 40010 Robotics under ``Objects/<cell name>``, in the standards' namespaces
(:mod:`cellrunner.plc.opcua_companions`).

Every variable is read-only for clients; the server refreshes them every 50 ms. Users are
operators or viewers; a viewer calls no method that acts (:mod:`cellrunner.plc.opcua_roles`).
Security: only the configured policies; username/password from the users file
(:mod:`cellrunner.plc.users`); client certificates must be in ``pki/trusted/``
(unknown ones are filed in ``pki/rejected/``); the server certificate is created in
``pki/own/`` on first start (:mod:`cellrunner.plc.pki`).

Bounds, so no client can exhaust the cell: at most :data:`MAX_CONNECTIONS` connections
(sessions included), a connection that does not log in within
:data:`LOGIN_GRACE_S` is closed, password checks (scrypt, tens of ms each) are limited
to :data:`LOGIN_BURST` at once refilled at :data:`LOGINS_PER_S` (a login beyond that is
refused at once, without hashing), RegisterServer is refused (the cell is no discovery
server), and StartJob's strings are bounded (:data:`MAX_TEXT`, reject code 11).

Password checks never run on the event loop (:mod:`cellrunner.plc.opcua_logins`): the
variables keep refreshing and other clients keep being answered while a flood of logins is
hashed.

The parts, one concern each: settings, names and bounds in :mod:`cellrunner.plc.opcua_config`,
``Objects/Cell`` in :mod:`cellrunner.plc.opcua_address_space`, its methods in
:mod:`cellrunner.plc.opcua_methods`, logins and certificates in
:mod:`cellrunner.plc.opcua_logins`; this module serves them (start, refresh, stop).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any
from urllib.parse import urlparse

from cellrunner.errors import CellrunnerError
from cellrunner.plc.opcua_address_space import CellObject, last_job_values
from cellrunner.plc.opcua_config import (
    APPLICATION_URI,
    DEFAULT_SECURITY,
    LOGIN_BURST,
    LOGIN_GRACE_S,
    LOGIN_WORKER_NICE,
    LOGIN_WORKERS,
    LOGINS_PER_S,
    MAX_CONNECTIONS,
    MAX_INT_DIGITS,
    MAX_JSON_DEPTH,
    MAX_PENDING_LOGINS,
    MAX_PENDING_PER_SOURCE,
    MAX_REMEMBERED_CLIENT_JOBS,
    MAX_TEXT,
    NAMESPACE_URI,
    NULL_DATETIME,
    POLICY_TYPES,
    REFRESH_PERIOD_S,
    SECURITY_POLICIES,
    SOURCE,
    OpcUaConfig,
    normalize_policy,
)
from cellrunner.plc.opcua_logins import HashedUserManager, bound, make_validator
from cellrunner.plc.opcua_methods import CellMethods, parse_job_parameters
from cellrunner.plc.port import CellPort, CellStatus, JobResult

__all__ = [
    "APPLICATION_URI",
    "DEFAULT_SECURITY",
    "LOGINS_PER_S",
    "LOGIN_BURST",
    "LOGIN_GRACE_S",
    "LOGIN_WORKERS",
    "LOGIN_WORKER_NICE",
    "MAX_CONNECTIONS",
    "MAX_INT_DIGITS",
    "MAX_JSON_DEPTH",
    "MAX_PENDING_LOGINS",
    "MAX_PENDING_PER_SOURCE",
    "MAX_REMEMBERED_CLIENT_JOBS",
    "MAX_TEXT",
    "NAMESPACE_URI",
    "NULL_DATETIME",
    "REFRESH_PERIOD_S",
    "SECURITY_POLICIES",
    "SOURCE",
    "HashedUserManager",
    "OpcUaConfig",
    "OpcUaServer",
    "normalize_policy",
    "parse_job_parameters",
]

_log = logging.getLogger(__name__)


class OpcUaServer:
    """The OPC UA server of one cell. Construct (no I/O), ``await start()``,
    ``await stop()`` on the caller's asyncio loop (a
    :class:`~cellrunner.plc.server.PlcServer`)."""

    name = "opcua"

    def __init__(self, port: CellPort, config: OpcUaConfig, *, cell_name: str = "cell") -> None:
        self.port = port
        self.config = config
        self.cell_name = cell_name
        self._server: Any = None
        self._cell = CellObject()
        self._methods = CellMethods(port, SOURCE)
        self._ruleset: Any = None
        self._companions: Any = None
        self._refresh_task: asyncio.Task[None] | None = None
        self._remove_listener: Callable[[], None] | None = None
        self._results: asyncio.Queue[JobResult] | None = None

    @property
    def endpoint(self) -> str:
        return self.config.endpoint

    @property
    def connected_clients(self) -> int:
        """OPC UA clients connected now (read from any thread: a list's length)."""
        bserver = getattr(self._server, "bserver", None)
        return len(getattr(bserver, "clients", ()) or ())

    @property
    def link_up(self) -> bool:
        """An OPC UA client is connected."""
        return self.connected_clients > 0

    @property
    def published_at(self) -> str:
        return self.endpoint

    # -- lifecycle -------------------------------------------------------------------------
    async def start(self) -> None:
        from asyncua import ua
        from asyncua.server.server import Server

        from cellrunner.plc.opcua_roles import RoleRuleset
        from cellrunner.plc.pki import Pki, default_hosts

        pki = Pki(self.config.pki_dir)
        allow_insecure = "none" in self.config.security
        users = HashedUserManager(self.config.users_file, pki, allow_insecure)
        users.load()  # InputError now, not at the first login
        cert_file, key_file = pki.ensure_server_certificate(
            APPLICATION_URI, default_hosts(urlparse(self.config.endpoint).hostname)
        )
        # never asyncua's PermissiveUserManager; ours is duck-typed (asyncua is imported lazily)
        server = Server(user_manager=users)  # type: ignore[arg-type]
        try:
            await server.init()
            bound(server.iserver)
            server.set_endpoint(self.config.endpoint)
            server.set_server_name(f"cellrunner {self.cell_name}")
            await server.set_application_uri(APPLICATION_URI)
            server.allow_remote_admin(False)
            ruleset = RoleRuleset(users.role_of)  # clients never write; viewers only read
            self._ruleset = ruleset
            server.set_security_policy(
                [getattr(ua.SecurityPolicyType, POLICY_TYPES[p]) for p in self.config.security],
                permission_ruleset=ruleset,  # type: ignore[arg-type]  # any PermissionRuleset
            )
            server.set_identity_tokens([ua.UserNameIdentityToken])
            await server.load_certificate(str(cert_file))
            await server.load_private_key(str(key_file))
            server.set_certificate_validator(make_validator(pki))
            await self._build_address_space(server)
            await self._publish_status(self.port.status(), initial=True)
            await server.start()
        except CellrunnerError:
            raise
        except Exception as exc:  # asyncua, cryptography and sockets fail in their own types
            raise CellrunnerError(
                f"OPC UA server failed to start on {self.config.endpoint}: {exc}"
            ) from exc
        self._server = server
        loop = asyncio.get_running_loop()
        self._results = asyncio.Queue()
        results = self._results
        self._remove_listener = self.port.add_result_listener(
            lambda result: loop.call_soon_threadsafe(results.put_nowait, result)
        )
        self._refresh_task = asyncio.create_task(self._refresh_loop(), name="opcua-refresh")

    async def stop(self) -> None:
        if self._remove_listener is not None:
            self._remove_listener()
            self._remove_listener = None
        if self._refresh_task is not None:
            self._refresh_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._refresh_task
            self._refresh_task = None
        if self._server is not None:
            await self._server.stop()
            self._server.iserver.user_manager.close()
            self._server = None

    # -- address space ---------------------------------------------------------------------
    async def _build_address_space(self, server: Any) -> None:
        idx = await server.register_namespace(NAMESPACE_URI)
        await self._cell.build(server, idx, self._methods)
        from cellrunner.plc.opcua_companions import Companions

        self._companions = Companions(self.port, SOURCE)  # SPEC 13: the plant's language
        await self._companions.build(server, idx, self.cell_name)
        if self._ruleset is not None:
            self._ruleset.reading_methods.update(self._companions.reading_methods)

    def start_job(self, task_name: str, params_text: str, client_job_id: str) -> tuple[str, int]:
        """StartJob's logic: (JobId, ReturnCode); idempotent per non-empty ClientJobId.
        Over-long strings are refused with 11 (bad params) before anything else."""
        return self._methods.start_job(task_name, params_text, client_job_id)

    # -- keeping values current ------------------------------------------------------------
    async def _refresh_loop(self) -> None:
        """Completions as they come (values first, then the event); status every 50 ms."""
        assert self._results is not None
        while True:
            try:
                result: JobResult | None = await asyncio.wait_for(
                    self._results.get(), REFRESH_PERIOD_S
                )
            except TimeoutError:
                result = None
            try:
                if result is not None:
                    await self._publish_result(result)
                else:
                    await self._publish_status(self.port.status())
            except Exception:  # the engine failed us; keep serving
                _log.exception("OPC UA refresh failed")

    async def _publish_status(self, status: CellStatus, *, initial: bool = False) -> None:
        values = self._cell.status_values(status, initial=initial)
        values.update(await self._cell.conveyor_values(status))
        await self._cell.write_values(values)
        if self._companions is not None:
            await self._companions.publish(status)

    async def _publish_result(self, result: JobResult) -> None:
        await self._cell.write_values(last_job_values(result))
        if self._companions is not None:
            await self._companions.finish(result)
        await self._publish_status(self.port.status())
        await self._cell.trigger_completion(result)
