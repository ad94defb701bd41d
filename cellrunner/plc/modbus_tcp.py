"""The Modbus TCP transport: pymodbus's asyncio server around a register image.

pymodbus 3.16 keeps at most 264 received bytes per connection (``max_buffer_size`` of
its socket framer) and drops the whole buffer beyond that, so a PLC that pipelines 23
writes in one TCP segment loses all of them unanswered; it also answers one frame per
``data_received``. Here each connection keeps its own buffer: every complete frame of
what arrived is cut off (:func:`cut_frames`), decoded and answered in the order it came,
and a partial frame waits for the rest. A header no Modbus TCP frame can have (protocol
id not 0, length outside 2..254) closes the connection, as the standard says.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Sequence
from typing import Any, Protocol

# Register function codes; writes read back with their own code. Coils and discrete
# inputs (1, 2, 5, 15) do not exist here: ILLEGAL FUNCTION.
REGISTER_FCS = frozenset({3, 4, 6, 16, 22, 23})
WRITE_FCS = frozenset({6, 16, 22, 23})

MBAP_BYTES = 6  # transaction id, protocol id, length (unit id and PDU follow)
MAX_LENGTH = 254  # unit id + the largest PDU (253 bytes)


class Registers(Protocol):
    """What the server asks of the register image (a ``ModbusLink``)."""

    def read(self, address: int, count: int) -> list[int] | int: ...

    def write(self, address: int, values: Sequence[int]) -> int | None: ...


def cut_frames(buffer: bytes) -> tuple[list[bytes], bytes | None]:
    """``(complete frames, the partial rest)`` of the bytes received so far; the rest is
    None after a header with a protocol id other than 0 or a length outside 2..254, since
    nothing after it can be framed again."""
    frames: list[bytes] = []
    at = 0
    while len(buffer) - at >= MBAP_BYTES:
        protocol = int.from_bytes(buffer[at + 2 : at + 4], "big")
        length = int.from_bytes(buffer[at + 4 : at + 6], "big")
        if protocol != 0 or not 2 <= length <= MAX_LENGTH:
            return frames, None
        end = at + MBAP_BYTES + length
        if end > len(buffer):
            break
        frames.append(buffer[at:end])
        at = end
    return frames, buffer[at:]


def tcp_server(registers: Registers, address: tuple[str, int]) -> Any:
    """A pymodbus ``ModbusTcpServer`` (not started) whose every request goes to
    ``registers``."""
    return _server_class()(_make_context(registers), address=address)


def _make_context(registers: Registers) -> Any:
    """A pymodbus server context that routes every request to ``registers``."""
    from pymodbus.constants import ExcCodes
    from pymodbus.datastore import ModbusServerContext

    class LinkContext(ModbusServerContext):
        # Deliberately skips ModbusServerContext.__init__ (it wants SimDevices); the
        # server uses an "old simulator" context as is: async get/set per request.
        def __init__(self) -> None:
            self.old_simulator = True
            self.simdevices = []
            self._devices = {}

        def device_ids(self) -> list[int]:
            return [0]

        async def async_getValues(  # pymodbus's name
            self, device_id: int, func_code: int, address: int, count: int = 1
        ) -> list[int] | ExcCodes:
            if func_code not in REGISTER_FCS:
                return ExcCodes.ILLEGAL_FUNCTION
            values = registers.read(address, count)
            return ExcCodes(values) if isinstance(values, int) else values

        async def async_setValues(
            self,
            device_id: int,
            func_code: int,
            address: int,
            values: Sequence[int] | Sequence[bool],
        ) -> ExcCodes | None:
            if func_code not in WRITE_FCS:
                return ExcCodes.ILLEGAL_FUNCTION
            code = registers.write(address, [int(v) for v in values])
            return None if code is None else ExcCodes(code)

    return LinkContext()


def _server_class() -> Any:
    from pymodbus.server import ModbusTcpServer
    from pymodbus.server.requesthandler import ServerRequestHandler

    class FramedHandler(ServerRequestHandler):
        """One connection: our own buffer, every frame answered in order."""

        def datagram_received(self, data: bytes, addr: tuple[str, int] | None) -> None:
            # replaces pymodbus's buffering (it drops everything beyond 264 bytes)
            state = self.__dict__.setdefault("_framing", _Framing())
            if state.rest is None:
                return  # closing: what follows a broken header is not read
            frames, state.rest = cut_frames(state.rest + data)
            state.pending.extend((frame, addr) for frame in frames)
            if state.task is None or state.task.done():
                state.task = asyncio.ensure_future(self._answer_pending(state))

        async def _answer_pending(self, state: _Framing) -> None:
            while state.pending:
                if self.transport is None or self.transport.is_closing():
                    # the PLC gave up on this connection (a timeout) and may already ask
                    # again on another: what it sent here is never applied after that
                    state.pending.clear()
                    return
                frame, addr = state.pending.popleft()
                # decodes one frame: sets last_pdu, or answers an undecodable one at once
                ServerRequestHandler.callback_data(self, frame, addr)
                if self.last_pdu is not None:
                    await self.handle_request()  # type: ignore[no-untyped-call]  # pymodbus: unannotated
                    self.last_pdu = None
            if state.rest is None:
                self.transport.close()

        def handle_later(self) -> None:
            """pymodbus schedules each decoded frame here; _answer_pending answers it."""

    class FramedTcpServer(ModbusTcpServer):
        def callback_new_connection(self) -> Any:
            return FramedHandler(  # type: ignore[no-untyped-call]  # pymodbus: unannotated
                self, self.trace_packet, self.trace_pdu, self.trace_connect
            )

    return FramedTcpServer


class _Framing:
    """A connection's bytes not yet framed, frames not yet answered, and the task
    answering them."""

    def __init__(self) -> None:
        self.rest: bytes | None = b""  # None once a broken header was read
        self.pending: deque[tuple[bytes, Any]] = deque()
        self.task: asyncio.Future[None] | None = None
