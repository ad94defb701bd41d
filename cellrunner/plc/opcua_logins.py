"""Who may log in to the OPC UA server, and how a login is checked off the event loop.

Password checks never run on the event loop: asyncua checks a login synchronously inside
ActivateSession, so the server first reads the request's user token itself and hashes the
password on :data:`~cellrunner.plc.opcua_config.LOGIN_WORKERS` worker thread(s) (scrypt
releases the GIL), with at most :data:`~cellrunner.plc.opcua_config.MAX_PENDING_LOGINS`
checks waiting (more are refused at once); asyncua's check then takes that verdict.
Client certificates must be in ``pki/trusted/`` (unknown ones are filed in ``pki/rejected/``).
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from cellrunner.errors import CellrunnerError
from cellrunner.plc.opcua_admission import (
    HANDSHAKE_BURST,
    HANDSHAKES_PER_S,
    SourceBudgets,
    source_of,
)
from cellrunner.plc.opcua_admission import install as install_admission
from cellrunner.plc.opcua_config import (
    LOGIN_BURST,
    LOGIN_GRACE_S,
    LOGIN_WORKER_NICE,
    LOGIN_WORKERS,
    LOGINS_PER_S,
    MAX_CONNECTIONS,
    MAX_PENDING_LOGINS,
    MAX_PENDING_PER_SOURCE,
)
from cellrunner.plc.opcua_ua import node_id
from cellrunner.thread_priority import nice

_log = logging.getLogger(__name__)

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


def bound(iserver: Any) -> None:
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
    activate = node_id(ua.object_ids.ObjectIds.ActivateSessionRequest_Encoding_DefaultBinary)
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


def make_validator(pki: Any) -> Callable[..., Any]:
    """asyncua certificate validator: trusted/ or refuse (and file in rejected/)."""

    async def validate(cert: Any, app_description: Any) -> None:
        from asyncua import ua
        from asyncua.common.utils import ServiceError

        if not pki.is_trusted(cert):
            path = pki.reject(cert)
            _log.warning("untrusted OPC UA client certificate filed as %s", path)
            raise ServiceError(ua.status_codes.StatusCodes.BadCertificateUntrusted)

    return validate
