"""Run the configured PLC servers (Modbus TCP, OPC UA), each on its own asyncio loop in
its own thread.

``cellrunner serve`` builds the engine (a :class:`~cellrunner.plc.port.CellPort`),
then::

    service = PlcService(engine, cell.plc, resolve=loaded_cell.resolve,
                         pki_dir=journal_dir / "pki", cell_name=cell.cell)
    service.start()          # raises CellrunnerError when a server cannot start
    ...                      # until SIGTERM
    service.stop()

``plc_config`` is the cell file's ``plc`` section: a mapping or an object with
``modbus`` and ``opcua`` attributes; either may be absent (that server stays off).
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cellrunner.errors import CellrunnerError
from cellrunner.plc.modbus import ModbusConfig, ModbusServer
from cellrunner.plc.port import CellPort
from cellrunner.plc.server import PlcServer

if TYPE_CHECKING:
    from cellrunner.plc.opcua import OpcUaServer
from cellrunner.thread_priority import nice


def _section(config: Any, name: str) -> Any:
    if config is None:
        return None
    if isinstance(config, dict):
        return config.get(name)
    return getattr(config, name, None)


class _ServerThread:
    """One :class:`PlcServer` on its own asyncio loop in its own thread, so nothing one
    server does (an OPC UA login hashing a password, a slow client) can delay another (the
    Modbus heartbeat)."""

    def __init__(self, name: str, make: Callable[[], PlcServer]) -> None:
        self.name = name
        self._make = make  # called on the thread's loop
        self.server: PlcServer | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stopped: asyncio.Event | None = None

    def start(self, timeout_s: float) -> None:
        started: Future[None] = Future()
        self._thread = threading.Thread(
            target=self._run, args=(started,), name=self.name, daemon=True
        )
        self._thread.start()
        try:
            started.result(timeout=timeout_s)
        except TimeoutError as exc:
            self.stop()
            raise CellrunnerError(
                f"the {self.name} server did not start within {timeout_s:g} s"
            ) from exc
        except CellrunnerError:
            self.join()
            raise

    def stop(self, timeout_s: float = 10.0) -> None:
        loop, stopped = self._loop, self._stopped
        if loop is not None and stopped is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                loop.call_soon_threadsafe(stopped.set)
        self.join(timeout_s)

    def join(self, timeout_s: float = 10.0) -> None:
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)
            self._thread = None

    def _run(self, started: Future[None]) -> None:
        raise_thread_priority()
        try:
            asyncio.run(self._serve(started))
        except BaseException as exc:  # reported through the future
            if not started.done():
                started.set_exception(_translate(exc))

    async def _serve(self, started: Future[None]) -> None:
        self._loop = asyncio.get_running_loop()
        self._stopped = asyncio.Event()
        try:
            self.server = server = self._make()
            await server.start()
        except BaseException as exc:
            started.set_exception(_translate(exc))
            if self.server is not None:
                await self.server.stop()
            return
        started.set_result(None)
        await self._stopped.wait()
        await server.stop()


class PlcService:
    """Both PLC servers of one cell, each on its own thread and asyncio loop."""

    def __init__(
        self,
        port: CellPort,
        plc_config: Any,
        *,
        base_dir: Path | str = ".",
        pki_dir: Path | str | None = None,
        cell_name: str = "cell",
        resolve: Callable[[str], Path] | None = None,
    ) -> None:
        from cellrunner.plc.opcua import OpcUaConfig  # light: no asyncua import

        self.port = port
        self.cell_name = cell_name
        modbus = _section(plc_config, "modbus")
        opcua = _section(plc_config, "opcua")
        self.modbus_config = None if modbus is None else ModbusConfig.from_mapping(modbus)
        self.opcua_config = (
            None
            if opcua is None
            else OpcUaConfig.from_mapping(
                opcua, base_dir=Path(base_dir), pki_dir=pki_dir, resolve=resolve
            )
        )
        self._threads: list[_ServerThread] = []

    @property
    def modbus(self) -> ModbusServer | None:
        server = self._server("modbus")
        return server if isinstance(server, ModbusServer) else None

    @property
    def opcua(self) -> OpcUaServer | None:
        from cellrunner.plc.opcua import OpcUaServer  # light: no asyncua import

        server = self._server("opcua")
        return server if isinstance(server, OpcUaServer) else None

    def _server(self, name: str) -> PlcServer | None:
        return next((t.server for t in self._threads if t.name == name), None)

    # -- lifecycle -----------------------------------------------------------------------
    def start(self, timeout_s: float = 30.0) -> None:
        """Start the servers; returns once both listen, raises CellrunnerError if not."""
        if self._threads:
            return
        # OPC UA first: building its address space holds the GIL for seconds, which would
        # stall a Modbus server already answering (its heartbeat) during start-up
        if self.opcua_config is not None:
            opcua_config = self.opcua_config

            def make_opcua() -> PlcServer:
                from cellrunner.plc.opcua import OpcUaServer

                return OpcUaServer(self.port, opcua_config, cell_name=self.cell_name)

            self._threads.append(_ServerThread("opcua", make_opcua))
        if self.modbus_config is not None:
            config = self.modbus_config
            self._threads.append(_ServerThread("modbus", lambda: ModbusServer(self.port, config)))
        try:
            for thread in self._threads:
                thread.start(timeout_s)
        except CellrunnerError:
            self.stop()
            raise

    def stop(self, timeout_s: float = 10.0) -> None:
        """Stop both servers and their threads; idempotent."""
        for thread in reversed(self._threads):
            thread.stop(timeout_s)
        self._threads = []

    def __enter__(self) -> PlcService:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def modbus_address(self) -> tuple[str, int] | None:
        return None if self.modbus is None else self.modbus.address

    @property
    def opcua_endpoint(self) -> str | None:
        return None if self.opcua is None else self.opcua.endpoint

    def links(self) -> dict[str, bool]:
        """Whether each configured PLC link is up, for the status page and metrics:
        Modbus while the PLC heartbeat keeps changing, OPC UA while a client is
        connected. Reads plain attributes only (safe from any thread)."""
        out: dict[str, bool] = {}
        for name, config in (("modbus", self.modbus_config), ("opcua", self.opcua_config)):
            if config is not None:
                server = self._server(name)
                out[name] = server is not None and server.link_up
        return out


def _translate(exc: BaseException) -> BaseException:
    if isinstance(exc, CellrunnerError):
        return exc
    return CellrunnerError(f"PLC servers failed to start: {type(exc).__name__}: {exc}")


#: nice value a PLC server thread asks for: the link's heartbeat must keep beating while
#: planning and the control loop load the cores
PLC_THREAD_NICE = -10


def raise_thread_priority() -> bool:
    """Run the calling thread at :data:`PLC_THREAD_NICE`; False where the OS does not allow
    it (no CAP_SYS_NICE, not Linux), which leaves the default priority. Threads it starts
    afterwards inherit the priority (Linux)."""
    return nice(PLC_THREAD_NICE)
