"""OPC UA server: SPEC section 8 (asyncua, imported lazily).

Address space (namespace ``urn:cellrunner``)::

    Objects/Cell                       EventNotifier: JobCompletedEventType
      State Int32, StateName String, Ready/Busy/ProtectiveStop/EmergencyStop Boolean,
      CurrentJobId String, CurrentStep Int32, ProdProcessed/ProdDefective UInt32
      LastJob/  JobId String, ResultCode Int32, ResultText String, CycleTime Double (s),
                EndTime DateTime
      StartJob(TaskName, Parameters JSON, ClientJobId) -> (JobId, ReturnCode)
      Reset() Hold() Unhold() Abort() Clear() Stop()

Every variable is read-only for clients; the server refreshes them every 50 ms.
Security: only the configured policies; username/password from the users file
(:mod:`cellrunner.plc.users`); client certificates must be in ``pki/trusted/``
(unknown ones are filed in ``pki/rejected/``); the server certificate is created in
``pki/own/`` on first start (:mod:`cellrunner.plc.pki`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from cellrunner.errors import InputError

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
    users_file: Path = Path("secrets/opcua-users.yaml")
    pki_dir: Path = Path("pki")

    @classmethod
    def from_mapping(
        cls, data: Any, *, base_dir: Path = Path("."), pki_dir: Path | str | None = None
    ) -> OpcUaConfig:
        """From the cell file mapping or model object; relative paths from ``base_dir``.

        ``pki_dir`` is the default PKI directory (SPEC: ``pki/`` beside the journal)
        used when the section has no ``pki`` key.
        """
        get = data.get if isinstance(data, dict) else lambda k, d=None: getattr(data, k, d)
        endpoint = str(get("endpoint", cls.endpoint))
        url = urlparse(endpoint)
        if url.scheme != "opc.tcp" or not url.hostname:
            raise InputError(
                f"plc.opcua.endpoint {endpoint!r} is not an opc.tcp://HOST:PORT/PATH URL"
            )
        security = tuple(normalize_policy(p) for p in (get("security", None) or DEFAULT_SECURITY))
        users = Path(str(get("users", cls.users_file)))
        pki = get("pki", None)
        pki_path = Path(str(pki)) if pki is not None else Path(pki_dir or "pki")
        return cls(
            endpoint=endpoint,
            security=security,
            users_file=users if users.is_absolute() else base_dir / users,
            pki_dir=pki_path if pki_path.is_absolute() else base_dir / pki_path,
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
