"""Who gets into the OPC UA server when many try at once (asyncua, imported lazily).

A flood must never lock the real PLC out, nor cost the cell more than a bounded share of
the CPU:

* **Per source.** Budgets are kept per source: the client certificate's thumbprint
  when the channel has one, else the peer's address (:func:`source_of`). A flood from
  one source spends its own budget, never the PLC's.
* **Handshakes.** Opening a secure channel costs asymmetric crypto; a client
  certificate gets :data:`HANDSHAKE_BURST` at once refilled at :data:`HANDSHAKES_PER_S`,
  and a channel opened beyond that is closed before any of it is decrypted (a channel
  on the None policy costs no crypto: the cap and the login grace bound those).
* **Connection cap.** At the cap, a new connection takes the slot of the oldest one
  that has no logged-in session (first those with no client certificate either), so a
  connection that authenticates always finds room; only when every slot holds a
  logged-in session is the new one refused.

:func:`install` patches asyncua's connection protocol and message processor once per
process; servers without :func:`install` keep asyncua's own behaviour.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections import OrderedDict
from typing import Any

_log = logging.getLogger(__name__)

#: secure channels a source may open back to back, and their refill rate (per s)
HANDSHAKE_BURST, HANDSHAKES_PER_S = 6, 2.0
#: sources remembered at once (the least recently seen are forgotten)
MAX_SOURCES = 1024


class TokenBucket:
    """``burst`` at once, refilled at ``per_s``; ``clock`` returns monotonic seconds."""

    def __init__(self, burst: float, per_s: float, clock: Any = time.monotonic) -> None:
        self.burst, self.per_s, self.clock = burst, per_s, clock
        self._tokens = float(burst)
        self._at = clock()

    def take(self) -> bool:
        now = self.clock()
        self._tokens = min(self.burst, self._tokens + (now - self._at) * self.per_s)
        self._at = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True


class SourceBudgets:
    """A token bucket per source (thread-safe), at most ``max_sources`` remembered."""

    def __init__(
        self,
        burst: float,
        per_s: float,
        clock: Any = time.monotonic,
        max_sources: int = MAX_SOURCES,
    ) -> None:
        self.burst, self.per_s, self.clock, self.max_sources = burst, per_s, clock, max_sources
        self._buckets: OrderedDict[str, TokenBucket] = OrderedDict()
        self._lock = threading.Lock()

    def take(self, source: str) -> bool:
        with self._lock:
            bucket = self._buckets.pop(source, None) or TokenBucket(
                self.burst, self.per_s, self.clock
            )
            self._buckets[source] = bucket  # most recently seen last
            while len(self._buckets) > self.max_sources:
                self._buckets.popitem(last=False)
            return bucket.take()


def source_of(certificate: bytes | None, peername: Any) -> str:
    """``cert:THUMBPRINT`` (SHA-1 of the DER, as OPC UA names certificates) or
    ``addr:IP``."""
    if certificate:
        return "cert:" + hashlib.sha1(bytes(certificate), usedforsecurity=False).hexdigest()
    host = peername[0] if isinstance(peername, tuple) and peername else str(peername)
    return f"addr:{host}"


def install(iserver: Any, handshakes: SourceBudgets) -> None:
    """Give ``iserver`` (asyncua's InternalServer) the handshake budget and the cap that
    keeps room for logged-in sessions (see the module docstring)."""
    iserver.cellrunner_handshakes = handshakes
    _patch_connections()
    _patch_handshakes()


def _level(protocol: Any) -> int:
    """2: a logged-in session; 1: a channel with a (trusted) client certificate; 0: else."""
    processor = getattr(protocol, "processor", None)
    session = getattr(processor, "session", None)
    if session is not None and session.is_activated():
        return 2
    policy = getattr(getattr(processor, "_connection", None), "security_policy", None)
    return 1 if getattr(policy, "peer_certificate", None) else 0


def _patch_connections() -> None:
    from asyncua.server.binary_server_asyncio import OPCUAProtocol

    if getattr(OPCUAProtocol, "_cellrunner_cap", False):
        return
    made: Any = OPCUAProtocol.connection_made

    def connection_made(self: Any, transport: Any) -> None:
        iserver = self.iserver
        if (
            getattr(iserver, "cellrunner_handshakes", None) is not None
            and len(self.clients) >= iserver.max_connections
        ):
            waiting = [c for c in self.clients if _level(c) < 2]
            if waiting:  # the oldest of the lowest level gives its slot up
                victim = min(waiting, key=_level)
                _log.warning(
                    "OPC UA connection from %s closed at the cap of %d: %s needs its slot",
                    victim.peer_name,
                    iserver.max_connections,
                    transport.get_extra_info("peername"),
                )
                self.clients.remove(victim)
                if victim.transport is not None:
                    victim.transport.close()
        made(self, transport)

    setattr(OPCUAProtocol, "connection_made", connection_made)  # noqa: B010 - patched
    setattr(OPCUAProtocol, "_cellrunner_cap", True)  # noqa: B010 - installed once


def _patch_handshakes() -> None:
    from asyncua import ua
    from asyncua.server.uaprocessor import UaProcessor
    from asyncua.ua.ua_binary import struct_from_binary

    if getattr(UaProcessor, "_cellrunner_handshakes", False):
        return
    process: Any = UaProcessor.process

    async def process_within_budget(self: Any, header: Any, body: Any) -> Any:
        budgets = getattr(self.iserver, "cellrunner_handshakes", None)
        if (
            budgets is not None
            and header.MessageType == ua.MessageType.SecureOpen
            and not self._connection.is_open()  # a new channel, not a renewal
        ):
            try:
                sender = struct_from_binary(
                    ua.AsymmetricAlgorithmHeader, body.copy(header.body_size)
                ).SenderCertificate
            except Exception:  # asyncua's own parsing answers a malformed header
                sender = None
            source = source_of(sender, self._transport.get_extra_info("peername"))
            if sender and not budgets.take(source):  # None policy: no crypto to bound
                _log.warning("OPC UA secure channel refused: %s opens too many", source)
                return False  # closes the connection before any crypto
        return await process(self, header, body)

    setattr(UaProcessor, "process", process_within_budget)  # noqa: B010 - patched
    setattr(UaProcessor, "_cellrunner_handshakes", True)  # noqa: B010 - installed once
