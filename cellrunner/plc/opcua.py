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

Password checks never run on the event loop: asyncua checks a login synchronously inside
ActivateSession, so the server first reads the request's user token itself and hashes the
password on :data:`LOGIN_WORKERS` worker thread(s) (scrypt releases the GIL), with at most
:data:`MAX_PENDING_LOGINS` checks waiting (more are refused at once); asyncua's check then
takes that verdict. The variables keep refreshing and other clients keep being answered
while a flood of logins is hashed.
"""

from __future__ import annotations

import asyncio
import contextlib
import contextvars
import json
import logging
import math
from collections import Counter, OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlparse

from cellrunner.errors import CellrunnerError, InputError
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.params import ParamValue
from cellrunner.plc.opcua_admission import (
    HANDSHAKE_BURST,
    HANDSHAKES_PER_S,
    SourceBudgets,
    source_of,
)
from cellrunner.plc.opcua_admission import install as install_admission
from cellrunner.plc.opcua_conveyors import ConveyorNodes
from cellrunner.plc.port import CellPort, CellStatus, JobResult, JobSource, ResultCode
from cellrunner.thread_priority import nice

if TYPE_CHECKING:
    from asyncua import ua

_log = logging.getLogger(__name__)

NAMESPACE_URI = "urn:cellrunner"
APPLICATION_URI = "urn:cellrunner:server"

#: Security policy names accepted in ``plc.opcua.security``.
SECURITY_POLICIES = (
    "Basic256Sha256_SignAndEncrypt",
    "Basic256Sha256_Sign",
    "Aes128Sha256RsaOaep_SignAndEncrypt",
    "Aes128Sha256RsaOaep_Sign",
    "Aes256Sha256RsaPss_SignAndEncrypt",
    "Aes256Sha256RsaPss_Sign",
    "none",
)
DEFAULT_SECURITY = ("Basic256Sha256_SignAndEncrypt",)


@dataclass(frozen=True)
class OpcUaConfig:
    """The cell file's ``plc.opcua``, with paths resolved.

    ``pki_dir`` holds ``own/``, ``trusted/``, ``rejected/``.
    """

    endpoint: str = "opc.tcp://127.0.0.1:4840/cellrunner"
    security: tuple[str, ...] = DEFAULT_SECURITY
    users_file: Path = Path("var/opcua-users.yaml")
    pki_dir: Path = Path("pki")

    @classmethod
    def from_mapping(
        cls,
        data: Any,
        *,
        base_dir: Path = Path("."),
        pki_dir: Path | str | None = None,
        resolve: Callable[[str], Path] | None = None,
    ) -> OpcUaConfig:
        """From the cell file mapping or model object.

        Relative paths go through ``resolve`` (the cell's one lookup rule,
        :meth:`~cellrunner.model.load.LoadedCell.resolve`), else from ``base_dir``.
        ``pki_dir`` is the default PKI directory (SPEC: ``pki/`` beside the journal)
        used when the section has no ``pki`` key.
        """
        resolve = resolve or (lambda p: base_dir / p)
        get = data.get if isinstance(data, dict) else lambda k, d=None: getattr(data, k, d)
        endpoint = str(get("endpoint", cls.endpoint))
        url = urlparse(endpoint)
        if url.scheme != "opc.tcp" or not url.hostname:
            raise InputError(
                f"plc.opcua.endpoint {endpoint!r} is not an opc.tcp://HOST:PORT/PATH URL"
            )
        security = tuple(normalize_policy(p) for p in (get("security", None) or DEFAULT_SECURITY))
        pki = get("pki", None)
        return cls(
            endpoint=endpoint,
            security=security,
            users_file=resolve(str(get("users", None) or cls.users_file)),
            pki_dir=resolve(str(pki)) if pki is not None else Path(pki_dir or resolve("pki")),
        )


def normalize_policy(name: Any) -> str:
    """The canonical spelling of a security policy name (case-insensitive)."""
    text = str(name).strip()
    for known in SECURITY_POLICIES:
        if text.lower() == known.lower():
            return known
    raise InputError(
        f"unknown OPC UA security policy {text!r}; known: {', '.join(SECURITY_POLICIES)}"
    )


# -- server ------------------------------------------------------------------------------
_POLICY_TYPES = {
    "Basic256Sha256_SignAndEncrypt": "Basic256Sha256_SignAndEncrypt",
    "Basic256Sha256_Sign": "Basic256Sha256_Sign",
    "Aes128Sha256RsaOaep_SignAndEncrypt": "Aes128Sha256RsaOaep_SignAndEncrypt",
    "Aes128Sha256RsaOaep_Sign": "Aes128Sha256RsaOaep_Sign",
    "Aes256Sha256RsaPss_SignAndEncrypt": "Aes256Sha256RsaPss_SignAndEncrypt",
    "Aes256Sha256RsaPss_Sign": "Aes256Sha256RsaPss_Sign",
    "none": "NoSecurity",
}
REFRESH_PERIOD_S = 0.05
MAX_REMEMBERED_CLIENT_JOBS = 10_000
#: connections (logged in or not) the server accepts at once
MAX_CONNECTIONS = 32
#: a connection that has not logged in this long after connecting is closed (s): a PLC
#: connects and logs in within a second
LOGIN_GRACE_S = 10.0
#: password checks allowed back to back from one source, and their refill rate (per s)
LOGIN_BURST, LOGINS_PER_S = 10, 5.0
#: threads that hash passwords (one core at most, whatever the flood)
LOGIN_WORKERS = 1
#: password checks running or waiting for a worker, in all and from one source; a login
#: beyond that is refused at once (BadTooManyOperations)
MAX_PENDING_LOGINS, MAX_PENDING_PER_SOURCE = 8, 2
#: nice value of the hashing thread: below the PLC threads and the control loop, so a
#: flood's hashing only takes what the cores have left
LOGIN_WORKER_NICE = 10
#: the longest TaskName, ClientJobId and Parameters text StartJob accepts (characters)
MAX_TEXT = {"TaskName": 64, "ClientJobId": 128, "Parameters": 1024}
#: the most digits of an integer in Parameters (an int64 has 19)
MAX_INT_DIGITS = 19
#: how deep a Parameters JSON value may nest (a flat object of numbers is 1)
MAX_JSON_DEPTH = 3  # {name: {xyz: [...]}}: an object of pose params
NULL_DATETIME = datetime(1601, 1, 1, tzinfo=UTC)  # OPC UA's "no time"

# (browse name, VariantType name, initial value) of Objects/Cell's variables
_CELL_VARIABLES = (
    ("State", "Int32", 0),
    ("StateName", "String", ""),
    ("Ready", "Boolean", False),
    ("Busy", "Boolean", False),
    ("ProtectiveStop", "Boolean", False),
    ("EmergencyStop", "Boolean", False),
    ("Obstructed", "Boolean", False),
    ("HoldSource", "String", ""),  # who holds the cell (HoldSource's value), "" when none
    ("HoldReason", "String", ""),
    ("CurrentJobId", "String", ""),
    ("CurrentStep", "Int32", 0),
    ("ProdProcessed", "UInt32", 0),
    ("ProdDefective", "UInt32", 0),
)
_LAST_JOB_VARIABLES = (
    ("JobId", "String", ""),
    ("ResultCode", "Int32", 0),
    ("ResultText", "String", ""),
    ("CycleTime", "Double", 0.0),
    ("EndTime", "DateTime", NULL_DATETIME),
)
_COMMAND_METHODS = {
    "Reset": "reset",
    "Hold": "hold",
    "Unhold": "unhold",
    "Abort": "abort",
    "Clear": "clear",
    "Stop": "stop",
}


def _node_id(identifier: int | str, namespace: int = 0) -> ua.NodeId:
    """asyncua's NodeId of a plain int or str (its annotations ask for its own Int32 and
    String subclasses, which plain values are as far as the wire is concerned)."""
    from asyncua import ua

    return ua.NodeId(identifier, namespace)  # type: ignore[arg-type]


def _status(code: int) -> ua.StatusCode:
    """asyncua's StatusCode of a plain int (its annotation asks for its UInt32 subclass)."""
    from asyncua import ua

    return ua.StatusCode(code)  # type: ignore[arg-type]


def _refuse_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


def parse_job_parameters(text: str) -> dict[str, ParamValue | str] | None:
    """StartJob's Parameters: a JSON object of finite numbers, quantities with a unit
    ("250 ms") and poses ({"xyz": [m], "rpy": [deg]}) (empty text = {}); None if not
    (also for NaN/Infinity, integers of more than MAX_INT_DIGITS digits, over-long text, or
    nesting deeper than an object of poses, which is refused before it is parsed)."""
    if not text or not text.strip():
        return {}
    if len(text) > MAX_TEXT["Parameters"] or _nesting(text) > MAX_JSON_DEPTH:
        return None
    try:
        data = json.loads(text, parse_constant=_refuse_constant, parse_int=_bounded_int)
    except (ValueError, RecursionError):
        return None
    if not isinstance(data, dict):
        return None
    params: dict[str, ParamValue | str] = {}
    for name, value in data.items():
        if isinstance(value, dict):
            if not set(value) <= {"xyz", "rpy"} or not all(
                isinstance(v, list)
                and all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
                for v in value.values()
            ):
                return None
        elif isinstance(value, bool) or not isinstance(value, int | float | str):
            return None
        if isinstance(value, float) and not math.isfinite(value):
            return None
        params[str(name)] = value
    return params


def _bounded_int(text: str) -> int:
    """A JSON integer that a param can hold (int64 at most; a 1000-digit one is refused)."""
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def _nesting(text: str) -> int:
    """The deepest bracket nesting in ``text`` (strings counted too: an upper bound)."""
    depth = deepest = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


#: the verdict of the password check made off the event loop for the ActivateSession being
#: processed: (username, password, accepted)
_VERDICT: contextvars.ContextVar[tuple[str, str, bool] | None] = contextvars.ContextVar(
    "cellrunner_opcua_login_verdict", default=None
)


class HashedUserManager:
    """asyncua user manager: username/password against the users file, nothing else.

    Anonymous and certificate identities get no user; the channel's client certificate
    (when the channel is secured) must be in the trust list; with no secured channel
    the login is refused unless ``allow_insecure`` (the cell file says ``none``).
    The users file is re-read when it changes, so ``users add`` works while serving.

    In the server, :meth:`check_password` hashes on a worker before asyncua calls
    :meth:`get_user`, which then only reads that verdict (see the module docstring);
    called on its own, :meth:`get_user` hashes in place.
    """

    def __init__(
        self,
        users_file: Path,
        pki: Any,
        allow_insecure: bool,
        budget: SourceBudgets | None = None,
        *,
        max_pending: int = MAX_PENDING_LOGINS,
        max_pending_per_source: int = MAX_PENDING_PER_SOURCE,
    ) -> None:
        self.users_file = users_file
        self.pki = pki
        self.allow_insecure = allow_insecure
        self.budget = budget or SourceBudgets(LOGIN_BURST, LOGINS_PER_S)
        self.max_pending = max_pending
        self.max_pending_per_source = max_pending_per_source
        self._users: dict[str, str] = {}
        self._roles: dict[str, str] = {}
        self._stamp: tuple[float, int] | None = None
        self._workers: ThreadPoolExecutor | None = None
        self._pending: Counter[str] = Counter()  # per source; touched on the event loop only

    def load(self) -> None:
        from cellrunner.plc.users import load_user_entries

        stat = self.users_file.stat() if self.users_file.exists() else None
        entries = load_user_entries(self.users_file)
        self._users = {name: entry.hash for name, entry in entries.items()}
        self._roles = {name: entry.role for name, entry in entries.items()}
        self._stamp = None if stat is None else (stat.st_mtime, stat.st_size)

    def _current_users(self) -> dict[str, str]:
        try:
            stat = self.users_file.stat()
            if (stat.st_mtime, stat.st_size) != self._stamp:
                self.load()
        except (OSError, CellrunnerError):
            _log.warning("users file %s unreadable; keeping the previous users", self.users_file)
        return self._users

    def role_of(self, username: str) -> str:
        """``"operator"`` or ``"viewer"``; an unknown name is a viewer (it cannot log in)."""
        self._current_users()
        return self._roles.get(username, "viewer")

    def get_user(
        self,
        iserver: Any,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> Any:
        from asyncua.crypto.permission_rules import User, UserRole

        if username is None or password is None:
            return None  # anonymous or certificate identity: refused
        if not self._channel_trusted(certificate):
            return None
        verdict = _VERDICT.get()
        if verdict is not None and verdict[:2] == (username, password):
            accepted = verdict[2]
        elif iserver is not None:  # in the server, unchecked: never hash on the event loop
            accepted = False
        else:  # called on its own: hash here
            accepted = self._within_budget(username, "") and self._verify(username, password)
        return User(role=UserRole.User, name=username) if accepted else None

    async def check_password(
        self, username: str, password: str, certificate: Any, source: str = ""
    ) -> str:
        """On the event loop: the login's verdict, hashed on a worker thread: ``"ok"``,
        ``"refused"`` (an untrusted channel, a wrong password), or ``"busy"``, at once
        and without a hash, when ``source`` (:func:`source_of`) has spent its budget or
        has ``max_pending_per_source`` checks waiting, or ``max_pending`` wait in all."""
        if not self._channel_trusted(certificate):
            return "refused"
        pending = self._pending
        if pending[source] >= self.max_pending_per_source or pending.total() >= self.max_pending:
            _log.warning("OPC UA login refused for user %r: too many logins waiting", username)
            return "busy"
        if not self._within_budget(username, source):
            return "busy"
        if self._workers is None:
            self._workers = ThreadPoolExecutor(
                LOGIN_WORKERS, thread_name_prefix="opcua-login", initializer=_lower_priority
            )
        pending[source] += 1
        try:
            work = self._workers.submit(self._verify, username, password)
            return "ok" if await asyncio.wrap_future(work) else "refused"
        finally:
            pending[source] -= 1
            if pending[source] <= 0:
                del pending[source]

    def close(self) -> None:
        """Stop the worker (checks under way finish; none waits for them)."""
        if self._workers is not None:
            self._workers.shutdown(wait=False, cancel_futures=True)
            self._workers = None

    def _channel_trusted(self, certificate: Any) -> bool:
        """A secured channel's client certificate is trusted; no secured channel (None
        policy: b"" or None) only when the cell file allows it."""
        from cryptography import x509

        if not certificate:
            return self.allow_insecure
        try:
            cert = x509.load_der_x509_certificate(bytes(certificate))
        except ValueError:
            return False
        if not self.pki.is_trusted(cert):
            self.pki.reject(cert)
            return False
        return True

    def _within_budget(self, username: str, source: str) -> bool:
        if self.budget.take(source):
            return True
        # a login flood: refused without spending a hash on it
        _log.warning(
            "OPC UA login refused for user %r: too many logins at once from %s",
            username,
            source or "this caller",
        )
        return False

    def _verify(self, username: str, password: str) -> bool:
        from cellrunner.plc.users import verify_password

        if verify_password(self._current_users().get(username), password):
            return True
        _log.warning("OPC UA login refused for user %r", username)
        return False


#: StartJob's requester: a client gives each job its own ClientJobId, and the same one again
#: is the first job (SPEC 8)
SOURCE = JobSource("opcua", ids_name_jobs=True)


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
        self._nodes: dict[str, Any] = {}
        self._types: dict[str, Any] = {}
        self._values: dict[str, Any] = {}
        self._client_jobs: OrderedDict[str, tuple[str, int]] = OrderedDict()
        self._event: Any = None
        self._ruleset: Any = None
        self._companions: Any = None
        self._aspace: Any = None
        self._conveyors: ConveyorNodes | None = None
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
            _bound(server.iserver)
            server.set_endpoint(self.config.endpoint)
            server.set_server_name(f"cellrunner {self.cell_name}")
            await server.set_application_uri(APPLICATION_URI)
            server.allow_remote_admin(False)
            ruleset = RoleRuleset(users.role_of)  # clients never write; viewers only read
            self._ruleset = ruleset
            server.set_security_policy(
                [getattr(ua.SecurityPolicyType, _POLICY_TYPES[p]) for p in self.config.security],
                permission_ruleset=ruleset,  # type: ignore[arg-type]  # any PermissionRuleset
            )
            server.set_identity_tokens([ua.UserNameIdentityToken])
            await server.load_certificate(str(cert_file))
            await server.load_private_key(str(key_file))
            server.set_certificate_validator(_make_validator(pki))
            await self._build_address_space(server)
            await self._publish_status(self.port.status(), initial=True)
            await server.start()
        except CellrunnerError:
            raise
        except Exception as exc:
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
        from asyncua import ua

        self._aspace = server.iserver.aspace
        idx = await server.register_namespace(NAMESPACE_URI)
        cell = await server.nodes.objects.add_object(
            _node_id("Cell", idx), ua.QualifiedName("Cell", idx)
        )
        last = await cell.add_object(
            _node_id("Cell.LastJob", idx), ua.QualifiedName("LastJob", idx)
        )
        self._conveyors = ConveyorNodes(cell, idx, self._nodes, self._types)
        for parent, prefix, table in (
            (cell, "", _CELL_VARIABLES),
            (last, "LastJob.", _LAST_JOB_VARIABLES),
        ):
            for name, vtype, initial in table:
                key = prefix + name
                variant_type = getattr(ua.VariantType, vtype)
                node = await parent.add_variable(
                    _node_id(f"Cell.{key}", idx),
                    ua.QualifiedName(name, idx),
                    initial,
                    variant_type,
                )
                self._nodes[key] = node
                self._types[key] = variant_type
        string, int32 = ua.VariantType.String, ua.VariantType.Int32
        await cell.add_method(
            _node_id("Cell.StartJob", idx),
            ua.QualifiedName("StartJob", idx),
            self._start_job_method,
            [
                _argument("TaskName", string, "task name or PLC task number"),
                _argument("Parameters", string, "JSON object of task params"),
                _argument("ClientJobId", string, "caller's id; the same id returns the first job"),
            ],
            [
                _argument("JobId", string, "the cell's job id"),
                _argument("ReturnCode", int32, "0 accepted, else reject code 10/11/12"),
            ],
        )
        for name, command in _COMMAND_METHODS.items():
            await cell.add_method(
                _node_id(f"Cell.{name}", idx),
                ua.QualifiedName(name, idx),
                self._command_method(command),
                [],
                [],
            )
        etype = await server.create_custom_event_type(
            idx,
            "JobCompletedEventType",
            ua.object_ids.ObjectIds.BaseEventType,
            [
                ("JobId", string),
                ("ResultCode", int32),
                ("ResultText", string),
                ("ClientJobId", string),
            ],
        )
        self._event = await server.get_event_generator(etype, cell)
        await server.nodes.server.set_event_notifier([ua.EventNotifier.SubscribeToEvents])
        from cellrunner.plc.opcua_companions import Companions

        self._companions = Companions(self.port, SOURCE)  # SPEC 13: the plant's language
        await self._companions.build(server, idx, self.cell_name)
        if self._ruleset is not None:
            self._ruleset.reading_methods.update(self._companions.reading_methods)

    # -- methods ---------------------------------------------------------------------------
    async def _start_job_method(self, parent: Any, *args: Any) -> Any:
        from asyncua import ua

        if len(args) != 3:
            return _status(
                ua.status_codes.StatusCodes.BadArgumentsMissing
                if len(args) < 3
                else ua.status_codes.StatusCodes.BadTooManyArguments
            )
        if all(_is_string(a) for a in args):
            task_name, params_text, client_job_id = (_text(a) for a in args)
            job_id, code = self.start_job(task_name, params_text, client_job_id)
        else:  # a Null variant or another type: bad params, as a PLC reads a ReturnCode
            _log.warning("StartJob refused: arguments %s, not 3 Strings", _type_names(args))
            job_id, code = "", int(ResultCode.REJECT_BAD_PARAMS)
        return [ua.Variant(job_id, ua.VariantType.String), ua.Variant(code, ua.VariantType.Int32)]

    def start_job(self, task_name: str, params_text: str, client_job_id: str) -> tuple[str, int]:
        """StartJob's logic: (JobId, ReturnCode); idempotent per non-empty ClientJobId.
        Over-long strings are refused with 11 (bad params) before anything else."""
        for name, text in (
            ("TaskName", task_name),
            ("Parameters", params_text),
            ("ClientJobId", client_job_id),
        ):
            if len(text) > MAX_TEXT[name]:
                _log.warning(
                    "StartJob refused: %s of %d characters (at most %d)",
                    name,
                    len(text),
                    MAX_TEXT[name],
                )
                return "", int(ResultCode.REJECT_BAD_PARAMS)
        if client_job_id and client_job_id in self._client_jobs:
            return self._client_jobs[client_job_id]
        params = parse_job_parameters(params_text)
        if params is None:
            return "", int(ResultCode.REJECT_BAD_PARAMS)
        task: str | int = int(task_name) if task_name.strip().isdigit() else task_name.strip()
        ticket = self.port.start_job(task, params, client_job_id, SOURCE)
        if not ticket.accepted:
            return "", int(ticket.reject_code or ResultCode.REJECT_NOT_READY)  # the wire
        if client_job_id:
            self._client_jobs[client_job_id] = (ticket.job_id, int(ResultCode.OK))
            while len(self._client_jobs) > MAX_REMEMBERED_CLIENT_JOBS:
                self._client_jobs.popitem(last=False)
        return ticket.job_id, int(ResultCode.OK)

    def _command_method(self, command: str) -> Callable[..., Any]:
        async def call(parent: Any, *args: Any) -> Any:
            from asyncua import ua

            if args:
                return _status(ua.status_codes.StatusCodes.BadTooManyArguments)
            if not self.port.command(command, HoldSource.OPCUA):
                return _status(ua.status_codes.StatusCodes.BadInvalidState)
            return []

        return call

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
        values = {
            "State": status.state,
            "StateName": status.state_name,
            "Ready": status.ready,
            "Busy": status.busy,
            "ProtectiveStop": status.protective_stop,
            "EmergencyStop": status.estop,
            "Obstructed": status.obstructed,
            "HoldSource": status.hold_source,
            "HoldReason": status.hold_reason,
            "CurrentJobId": status.job_id,
            "CurrentStep": status.step_index,
            "ProdProcessed": min(max(status.parts_processed, 0), 0xFFFFFFFF),
            "ProdDefective": min(max(status.parts_defective, 0), 0xFFFFFFFF),
        }
        if initial and status.last_result is not None:
            values.update(_last_job_values(status.last_result))
        if self._conveyors is not None:  # SPEC 13: Cell.Conveyors.<name>.Speed, mm/s
            values.update(await self._conveyors.values(status.conveyor_speeds_mmps))
        await self._write_values(values)
        if self._companions is not None:
            await self._companions.publish(status)

    async def _publish_result(self, result: JobResult) -> None:
        await self._write_values(_last_job_values(result))
        if self._companions is not None:
            await self._companions.finish(result)
        await self._publish_status(self.port.status())
        await self._trigger_completion(result)

    async def _write_values(self, values: dict[str, Any]) -> None:
        from asyncua import ua

        aspace = self._aspace
        for key, value in values.items():
            if self._values.get(key, _MISSING) == value:
                continue
            self._values[key] = value
            variant = ua.Variant(value, self._types[key])
            await aspace.write_attribute_value(
                self._nodes[key].nodeid, ua.attribute_ids.AttributeIds.Value, ua.DataValue(variant)
            )

    async def _trigger_completion(self, result: JobResult) -> None:
        from asyncua import ua

        gen = self._event
        gen.event.JobId = result.job_id
        gen.event.ResultCode = int(result.result_code)  # the wire
        gen.event.ResultText = result.result_text
        gen.event.ClientJobId = result.client_job_id
        gen.event.Severity = 100 if result.result_code == ResultCode.OK else 500
        await gen.trigger(message=f"job {result.job_id} ended with {int(result.result_code)}")
        # the same event (same EventId) for clients subscribed on the Server object
        cell_node = gen.event.emitting_node
        gen.event.emitting_node = _node_id(ua.object_ids.ObjectIds.Server)
        try:
            await gen.isession.subscription_service.trigger_event(gen.event)
        finally:
            gen.event.emitting_node = cell_node


_MISSING = object()


def _bound(iserver: Any) -> None:
    """Caps on what clients may hold, and RegisterServer refused (see the module docstring)."""
    from asyncua import ua
    from asyncua.common.utils import ServiceError

    iserver.max_connections = MAX_CONNECTIONS
    iserver.max_pending_activation_seconds = LOGIN_GRACE_S
    install_admission(iserver, SourceBudgets(HANDSHAKE_BURST, HANDSHAKES_PER_S))

    def refuse_registration(*args: Any, **kwargs: Any) -> None:
        raise ServiceError(ua.status_codes.StatusCodes.BadServiceUnsupported)

    iserver.register_server = refuse_registration
    _check_logins_off_the_loop()


def _lower_priority() -> None:
    """Run the calling thread at :data:`LOGIN_WORKER_NICE` (it inherited the PLC thread's
    raised priority); lowering a priority is always allowed."""
    nice(LOGIN_WORKER_NICE)


def _check_logins_off_the_loop() -> None:
    """Make asyncua's ActivateSession await the password check of a
    :class:`HashedUserManager` (hashed on its worker) before it runs, instead of hashing
    inside its synchronous user check on the event loop. Installed once per process;
    servers with another user manager are left as they are."""
    from asyncua import ua
    from asyncua.common.utils import ServiceError
    from asyncua.server.uaprocessor import UaProcessor

    if getattr(UaProcessor, "_cellrunner_logins", False):
        return
    activate = _node_id(ua.object_ids.ObjectIds.ActivateSessionRequest_Encoding_DefaultBinary)
    process: Any = UaProcessor._process_message

    async def process_message(
        self: Any, typeid: Any, requesthdr: Any, seqhdr: Any, body: Any
    ) -> Any:
        manager = self.iserver.user_manager
        if typeid != activate or not isinstance(manager, HashedUserManager):
            return await process(self, typeid, requesthdr, seqhdr, body)
        verdict = await _login_verdict(self, manager, requesthdr, body.copy())
        if isinstance(verdict, str):  # "busy": a refusal for rate says so, with its status
            raise ServiceError(ua.status_codes.StatusCodes.BadTooManyOperations)
        token = _VERDICT.set(verdict)
        try:
            return await process(self, typeid, requesthdr, seqhdr, body)
        finally:
            _VERDICT.reset(token)

    setattr(UaProcessor, "_process_message", process_message)  # noqa: B010 - patched
    setattr(UaProcessor, "_cellrunner_logins", True)  # noqa: B010 - installed once


async def _login_verdict(
    processor: Any, manager: HashedUserManager, requesthdr: Any, body: Any
) -> tuple[str, str, bool] | str | None:
    """(username, password, accepted) of an ActivateSession's user token; ``"busy"`` when
    its source is over its login budget; None when it carries no token asyncua would pass
    to the user manager (asyncua then refuses it itself)."""
    from asyncua import ua
    from asyncua.ua.ua_binary import struct_from_binary

    try:
        params = struct_from_binary(ua.ActivateSessionParameters, body)
        token = params.UserIdentityToken
        # a session activated again on a new channel is found as asyncua finds it
        session = processor.session or processor.iserver.lookup_external_session(
            requesthdr.AuthenticationToken
        )
        if session is None or not isinstance(token, ua.UserNameIdentityToken):
            return None
        username, password = processor.iserver.decrypt_user_token(session, token)
    except Exception:  # a malformed token: asyncua's own handling answers it
        return None
    if username is None or password is None:
        return None
    certificate = processor._connection.security_policy.peer_certificate
    source = source_of(certificate, processor._transport.get_extra_info("peername"))
    verdict = await manager.check_password(username, password, certificate, source)
    return "busy" if verdict == "busy" else (username, password, verdict == "ok")


def _last_job_values(result: JobResult) -> dict[str, Any]:
    return {
        "LastJob.JobId": result.job_id,
        "LastJob.ResultCode": int(result.result_code),  # the wire
        "LastJob.ResultText": result.result_text,
        "LastJob.CycleTime": float(result.cycle_time_s),
        "LastJob.EndTime": result.end_time or NULL_DATETIME,
    }


def _argument(name: str, vtype: Any, description: str) -> Any:
    from asyncua import ua

    arg = ua.Argument()
    arg.Name = name
    arg.DataType = _node_id(vtype.value)
    arg.ValueRank = -1
    arg.Description = ua.LocalizedText(description)
    return arg


def _is_string(argument: Any) -> bool:
    """A String variant (asyncua passes Variants; a plain str from in-process calls)."""
    from asyncua import ua

    if isinstance(argument, ua.Variant):
        return argument.VariantType == ua.VariantType.String and (
            argument.Value is None or isinstance(argument.Value, str)
        )
    return isinstance(argument, str)


def _type_names(args: tuple[Any, ...]) -> str:
    return ", ".join(
        a.VariantType.name if hasattr(a, "VariantType") else type(a).__name__ for a in args
    )


def _text(variant: Any) -> str:
    value = getattr(variant, "Value", variant)
    return "" if value is None else str(value)


def _make_validator(pki: Any) -> Callable[..., Any]:
    """asyncua certificate validator: trusted/ or refuse (and file in rejected/)."""

    async def validate(cert: Any, app_description: Any) -> None:
        from asyncua import ua
        from asyncua.common.utils import ServiceError

        if not pki.is_trusted(cert):
            path = pki.reject(cert)
            _log.warning("untrusted OPC UA client certificate filed as %s", path)
            raise ServiceError(ua.status_codes.StatusCodes.BadCertificateUntrusted)

    return validate
