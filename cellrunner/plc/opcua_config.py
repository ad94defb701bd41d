"""The OPC UA server's settings (the cell file's ``plc.opcua``), names and bounds (SPEC 8).

Light: no asyncua import, so the cell file is checked without it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from cellrunner.errors import InputError
from cellrunner.plc.port import JobSource

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


#: asyncua's SecurityPolicyType member of each policy name
POLICY_TYPES = {
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

#: StartJob's requester: a client gives each job its own ClientJobId, and the same one again
#: is the first job (SPEC 8)
SOURCE = JobSource("opcua", ids_name_jobs=True)
