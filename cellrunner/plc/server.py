"""The PLC server Protocol: what :class:`~cellrunner.plc.service.PlcService` runs, one per
PLC protocol (Modbus TCP in :mod:`.modbus`, OPC UA in :mod:`.opcua`).

Lifecycle: construct (no I/O) -> ``await start()`` (listening when it returns; raises
CellrunnerError when it cannot) -> serving on the caller's asyncio loop -> ``await stop()``
(idempotent). The service gives each server its own thread and loop, so nothing one server
does delays another; ``link_up`` and ``published_at`` are read from any thread.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class PlcServer(Protocol):
    #: the protocol's name, as the status page's links and alarms name it ("modbus")
    name: str

    @property
    def link_up(self) -> bool:
        """The peer is there now: a plain attribute read, safe from any thread."""
        ...

    @property
    def published_at(self) -> str:
        """Where the server answers (``host:port``, an endpoint URL), for logs."""
        ...

    async def start(self) -> None:
        """Listen and serve on the running asyncio loop; raise CellrunnerError when it
        cannot (the port taken, a bad certificate)."""
        ...

    async def stop(self) -> None:
        """Stop serving and release the socket; idempotent."""
        ...
