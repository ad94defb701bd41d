"""Modbus TCP server: SPEC section 7, bit for bit.

Two layers, so the handshake can be tested tick by tick without sockets:

* :class:`ModbusLink` - the register image and the handshake logic (no I/O). It is
  driven by ``read``/``write`` (what the PLC asks), ``tick(now_s)`` (every 20 ms) and
  ``on_result`` (a job finished), all on one thread.
* :class:`ModbusServer` - pymodbus's asyncio TCP server around a link (see
  :mod:`cellrunner.plc.modbus_tcp`: every request of a segment answered, in order;
  writes outside 0-29 are answered with exception 02 ILLEGAL DATA ADDRESS, all or
  nothing).

Holding registers (0-based): the PLC writes 0-29 (20-29: conveyor encoders), the cell
writes 100-119; reads are allowed anywhere in 0-119. uint32 values are two registers,
high word first.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cellrunner.errors import CellrunnerError, InputError
from cellrunner.model.hold_source import HoldSource
from cellrunner.plc.modbus_tcp import tcp_server
from cellrunner.plc.param_registers import N_PARAM_REGS, PARAM_FIRST, decode_params
from cellrunner.plc.param_registers import to_int16 as to_int16  # re-exported: the register codec
from cellrunner.plc.port import (
    COMPLETED_CODES,
    CellPort,
    CellStatus,
    JobResult,
    JobSource,
    PackMLState,
    ResultCode,
)

# -- register map (SPEC section 7) -------------------------------------------------
HR_HEARTBEAT = 0
HR_COMMAND = 1
HR_JOB_ID = 2
HR_TASK = 3
HR_PARAMS = PARAM_FIRST  # 4..19, in the task's params: order (see param_registers)
#: conveyor encoder counts the PLC writes (SPEC section 13): uint32, high word first,
#: 20-21 for a conveyor with ``encoder: {source: plc, register: 20}``, up to 28-29
HR_ENCODERS = 20
PLC_FIRST, PLC_LAST = 0, 29

HR_CELL_HEARTBEAT = 100
HR_STATUS = 101
HR_STATE = 102
HR_JOB_ID_ECHO = 103
HR_RESULT_JOB_ID = 104
HR_RESULT_CODE = 105
HR_STEP = 106
HR_RETRIES = 107
HR_CYCLE_MS = 108  # uint32 108-109
HR_PROCESSED = 110  # uint32 110-111
HR_DEFECTIVE = 112  # uint32 112-113
HR_CONVEYOR_SPEED = 114  # the first conveyor's measured speed, mm/s (int16, SPEC 13)
CELL_FIRST, CELL_LAST = 100, 119
N_REGS = 120

_log = logging.getLogger(__name__)

# command bits (register 1)
CMD_JOB_REQ = 1 << 0
CMD_RESET = 1 << 1
CMD_ABORT = 1 << 2
CMD_HOLD = 1 << 3
CMD_UNHOLD = 1 << 4

# status bits (register 101)
ST_READY = 1 << 0
ST_JOB_ACK = 1 << 1
ST_BUSY = 1 << 2
ST_DONE = 1 << 3
ST_ERROR = 1 << 4
ST_HELD = 1 << 5
ST_PROTECTIVE_STOP = 1 << 6
ST_ESTOP = 1 << 7
ST_PLC_WATCHDOG = 1 << 8
ST_REJECTED = 1 << 9
ST_OBSTRUCTED = 1 << 10  # SPEC 12: the arm waits for an obstacle of the watched zone
HANDSHAKE_BITS = ST_JOB_ACK | ST_BUSY | ST_DONE | ST_ERROR | ST_REJECTED

CELL_HEARTBEAT_PERIOD_S = 0.05  # SPEC: increments every <= 200 ms; 50 ms leaves room for jitter
TICK_PERIOD_S = 0.02
RESET_TIMEOUT_S = 10.0

# Modbus exception codes
EXC_ILLEGAL_FUNCTION = 0x01
EXC_ILLEGAL_ADDRESS = 0x02


def split_uint32(value: int) -> tuple[int, int]:
    """``(high_word, low_word)``; values clamp to 0..2**32-1."""
    value = min(max(int(value), 0), 0xFFFFFFFF)
    return (value >> 16) & 0xFFFF, value & 0xFFFF


@dataclass(frozen=True)
class ModbusConfig:
    """The cell file's ``plc.modbus``: bind address, TCP port, PLC watchdog in s."""

    bind: str = "127.0.0.1"
    port: int = 502
    heartbeat_timeout_s: float = 1.5

    @classmethod
    def from_mapping(cls, data: Any) -> ModbusConfig:
        """From the cell file mapping (``heartbeat_timeout`` in s) or a model object."""
        get = data.get if isinstance(data, dict) else lambda k, d=None: getattr(data, k, d)
        timeout = get("heartbeat_timeout_s", None)
        if timeout is None:
            timeout = get("heartbeat_timeout", 1.5)
        port = int(get("port", 502))
        if not 0 <= port <= 65535:
            raise InputError(f"plc.modbus.port {port} outside 0..65535")
        if float(timeout) <= 0:
            raise InputError(f"plc.modbus.heartbeat_timeout {timeout} must be > 0 s")
        return cls(str(get("bind", "127.0.0.1")), port, float(timeout))


class ModbusLink:
    """Register image and handshake of SPEC section 7 (sans I/O, single-threaded).

    ``clock`` returns monotonic seconds; tests pass a fake one.
    """

    def __init__(
        self,
        port: CellPort,
        heartbeat_timeout_s: float = 1.5,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.port = port
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.clock = clock
        self.regs = [0] * N_REGS
        self._active_job: str | None = None  # engine job id of the Modbus job running
        self._active_plc_id = 0
        self._watchdog = False
        self._watchdog_armed = False  # arms on the first heartbeat change
        self._heartbeat_changed_s = 0.0
        self._cell_heartbeat_s = 0.0
        self._reset_until_s: float | None = None  # a RESET edge still being carried out
        self._clear_sent = False
        self._replay: JobResult | None = (
            None  # the last Modbus job's result, owed to a re-sent request
        )
        self.ack_times_s: dict[int, float] = {}  # PLC job id -> time of ACK (bench)
        #: the PLC's registers 0-29 as its last write of the encoder registers (20-29) left
        #: them, and how many such writes came so far: ``(writes, registers)``, replaced
        #: whole (one assignment, so another thread never reads half a uint32)
        self.encoder_registers: tuple[int, tuple[int, ...]] = (0, tuple(self.regs[: PLC_LAST + 1]))

    # -- start-up ------------------------------------------------------------------
    def restore(self) -> None:
        """Publish the last result (e.g. a job closed with 107 at start-up)."""
        now = self.clock()
        self._heartbeat_changed_s = now
        self._cell_heartbeat_s = now
        status = self.port.status()
        result = status.last_result
        if result is not None:
            self._write_result(result, status)
            if result.source == "modbus":
                self._replay = result  # a restart right after it ended: the PLC may ask again
        self._refresh(status)

    # -- requests from the PLC ---------------------------------------------------------
    def read(self, address: int, count: int) -> list[int] | int:
        """Registers ``address..address+count-1`` or a Modbus exception code."""
        if address < 0 or count < 1 or address + count > N_REGS:
            return EXC_ILLEGAL_ADDRESS
        return self.regs[address : address + count]

    def write(self, address: int, values: Sequence[int]) -> int | None:
        """Write PLC registers; None, or exception 02 when any address is not 0-29."""
        if address < PLC_FIRST or address + len(values) - 1 > PLC_LAST or not values:
            return EXC_ILLEGAL_ADDRESS
        old_heartbeat = self.regs[HR_HEARTBEAT]
        old_cmd = self.regs[HR_COMMAND]
        for offset, value in enumerate(values):
            self.regs[address + offset] = int(value) & 0xFFFF
        now = self.clock()
        if address <= HR_HEARTBEAT and self.regs[HR_HEARTBEAT] != old_heartbeat:
            self._heartbeat_changed_s = now
            self._watchdog_armed = True
            self._watchdog = False
        if address <= HR_COMMAND < address + len(values):
            self._on_command(old_cmd, self.regs[HR_COMMAND], now)
        if address + len(values) > HR_ENCODERS:
            writes = self.encoder_registers[0] + 1
            self.encoder_registers = (writes, tuple(self.regs[: PLC_LAST + 1]))
        self._refresh(self.port.status())
        return None

    # -- periodic ----------------------------------------------------------------------
    def tick(self, now_s: float | None = None) -> None:
        """Cell heartbeat, watchdog, status refresh; call every ~20 ms."""
        now = self.clock() if now_s is None else now_s
        if now - self._cell_heartbeat_s >= CELL_HEARTBEAT_PERIOD_S:
            self._cell_heartbeat_s = now
            self.regs[HR_CELL_HEARTBEAT] = (self.regs[HR_CELL_HEARTBEAT] + 1) & 0xFFFF
        status = self.port.status()
        if (
            self._watchdog_armed
            and not self._watchdog
            and now - self._heartbeat_changed_s > self.heartbeat_timeout_s
        ):
            self._watchdog = True
            if status.busy:
                self.port.command("hold", HoldSource.PLC_WATCHDOG)
            status = self.port.status()
        if self._reset_until_s is not None:
            if now > self._reset_until_s:
                self._reset_until_s = None
            elif self._drive_reset(status.state):
                status = self.port.status()
        last = status.last_result
        if self._active_job is not None and last is not None and last.job_id == self._active_job:
            self.on_result(last)  # a listener call lost or not yet delivered
        self._refresh(status)

    def on_result(self, result: JobResult) -> None:
        """A job finished: for the Modbus job, write 104-113 first, then DONE/ERROR."""
        if self._active_job is None or result.job_id != self._active_job:
            return
        self._active_job = None
        self._replay = result  # the same id asked again gets this result, never a second run
        status = self.port.status()
        self._write_result(result, status, plc_job_id=self._active_plc_id)
        # a request refused while the job ran (REJECTED, its id in 104) ends here: the
        # job's end shows only the job's own DONE or ERROR
        st = self.regs[HR_STATUS] & ~(ST_BUSY | ST_REJECTED)
        if self.regs[HR_COMMAND] & CMD_JOB_REQ:
            st |= ST_DONE if result.result_code in COMPLETED_CODES else ST_ERROR
        else:  # the PLC dropped JOB_REQ early: results are readable, handshake over
            st &= ~HANDSHAKE_BITS
        self.regs[HR_STATUS] = st
        self._refresh(status)

    @property
    def watchdog(self) -> bool:
        return self._watchdog

    @property
    def heartbeat_alive(self) -> bool:
        """The PLC heartbeat has changed and not stopped for ``heartbeat_timeout_s``."""
        return self._watchdog_armed and not self._watchdog

    # -- internals ---------------------------------------------------------------------
    def _on_command(self, old: int, new: int, now: float) -> None:
        rising = new & ~old
        if rising & CMD_ABORT:
            self.port.command("abort")
        if rising & CMD_HOLD:
            self.port.command("hold")
        if rising & CMD_UNHOLD:
            self.port.command("unhold")
        if rising & CMD_RESET:
            self._on_reset(now)
        if old & CMD_JOB_REQ and not new & CMD_JOB_REQ:
            self._on_job_release()
        if rising & CMD_JOB_REQ:
            self._on_job_request(now)

    def _on_reset(self, now: float) -> None:
        self._reset_until_s = now + RESET_TIMEOUT_S
        self._clear_sent = False
        self._drive_reset(self.port.status().state)

    def _drive_reset(self, state: int) -> bool:
        """One step of RESET: Aborted -> Clear, Stopped/Complete -> Reset, Idle with a
        protective stop latched -> Reset (the cell unlocks it).

        Waits through transient states (Aborting, Clearing, Stopping...), so a RESET
        pressed right after ABORT still ends in Idle. Returns True if it commanded.
        """
        if state == PackMLState.ABORTED:
            if self._clear_sent:
                return False  # the engine has not left Aborted yet
            self._clear_sent = True
            if not self.port.command("clear"):  # e.g. e-stop still pressed
                self._reset_until_s = None
                return False
            return True
        if state in (PackMLState.STOPPED, PackMLState.COMPLETE):
            self._reset_until_s = None
            return self.port.command("reset")
        if state == PackMLState.IDLE and self.port.status().protective_stop:
            self._reset_until_s = None  # a stop latched with no job: Reset unlocks it
            return self.port.command("reset")
        if state not in _TRANSIENT_STATES:
            self._reset_until_s = None
        return False

    def _on_job_release(self) -> None:
        st = self.regs[HR_STATUS]
        if self._active_job is None:
            st &= ~HANDSHAKE_BITS
        else:  # job still running: keep ACK/BUSY until it ends
            st &= ~(ST_DONE | ST_ERROR | ST_REJECTED)
        self.regs[HR_STATUS] = st

    def _on_job_request(self, now: float) -> None:
        plc_id = self.regs[HR_JOB_ID]
        task = self.regs[HR_TASK]
        if self._active_job is not None:
            if (
                plc_id == self._active_plc_id
            ):  # JOB_REQ toggled for the job that runs: still ACK+BUSY
                self._set_handshake(ST_JOB_ACK | ST_BUSY)
            else:  # another id while busy: REJECTED (no ERROR: that would read as the
                # running job's end) beside its ACK+BUSY, the refused id and 12 in 104/105
                self.regs[HR_RESULT_JOB_ID] = plc_id
                self.regs[HR_RESULT_CODE] = int(ResultCode.REJECT_NOT_READY)
                self.regs[HR_STATUS] |= ST_REJECTED
            return
        self.regs[HR_JOB_ID_ECHO] = plc_id
        if self._replay is not None and self._replay.client_job_id == str(plc_id):
            # the job this id names has ended (maybe before a restart): its result, not a second run
            result = self._replay
            self._write_result(result, self.port.status(), plc_job_id=plc_id)
            done = result.result_code in COMPLETED_CODES
            self._set_handshake(ST_JOB_ACK | (ST_DONE if done else ST_ERROR))
            return
        if plc_id == 0:
            self._reject(plc_id, ResultCode.REJECT_BAD_PARAMS)
            return
        status = self.port.status()
        if self._watchdog or not status.ready:
            self._reject(plc_id, ResultCode.REJECT_NOT_READY)
            return
        names = self.port.task_params(task)
        if names is None:
            self._reject(plc_id, ResultCode.REJECT_UNKNOWN_TASK)
            return
        specs = getattr(self.port, "task_param_specs", None)
        layout = specs(task) if specs is not None else [(name, "int", None) for name in names]
        params = decode_params(layout, self.regs[HR_PARAMS : HR_PARAMS + N_PARAM_REGS])
        ticket = self.port.start_job(task, params, str(plc_id), SOURCE)
        if not ticket.accepted:
            self._reject(plc_id, ticket.reject_code or ResultCode.REJECT_NOT_READY)
            return
        self._active_job = ticket.job_id
        self._active_plc_id = plc_id
        self.ack_times_s[plc_id] = now
        self._set_handshake(ST_JOB_ACK | ST_BUSY)

    def _reject(self, plc_id: int, code: ResultCode) -> None:
        self.regs[HR_RESULT_JOB_ID] = plc_id
        self.regs[HR_RESULT_CODE] = int(code)  # the wire
        self._set_handshake(ST_ERROR | ST_REJECTED)

    def _set_handshake(self, bits: int) -> None:
        self.regs[HR_STATUS] = (self.regs[HR_STATUS] & ~(HANDSHAKE_BITS | ST_READY)) | bits

    def _write_result(
        self, result: JobResult, status: CellStatus, plc_job_id: int | None = None
    ) -> None:
        if plc_job_id is None:
            plc_job_id = _plc_job_id(result)
        self.regs[HR_RESULT_JOB_ID] = plc_job_id
        self.regs[HR_RESULT_CODE] = int(result.result_code) & 0xFFFF  # the wire
        self.regs[HR_STEP] = status.step_index & 0xFFFF
        self.regs[HR_RETRIES] = min(result.retries, 0xFFFF)
        self.regs[HR_CYCLE_MS : HR_CYCLE_MS + 2] = split_uint32(round(result.cycle_time_s * 1000))
        self._write_counters(status)

    def _write_counters(self, status: CellStatus) -> None:
        self.regs[HR_PROCESSED : HR_PROCESSED + 2] = split_uint32(status.parts_processed)
        self.regs[HR_DEFECTIVE : HR_DEFECTIVE + 2] = split_uint32(status.parts_defective)

    def _refresh(self, status: CellStatus) -> None:
        st = self.regs[HR_STATUS] & HANDSHAKE_BITS
        handshake_idle = st == 0 and not self.regs[HR_COMMAND] & CMD_JOB_REQ
        if status.ready and handshake_idle and not self._watchdog and self._active_job is None:
            st |= ST_READY
        if status.held:
            st |= ST_HELD
        if status.protective_stop:
            st |= ST_PROTECTIVE_STOP
        if status.estop:
            st |= ST_ESTOP
        if self._watchdog:
            st |= ST_PLC_WATCHDOG
        if status.obstructed:
            st |= ST_OBSTRUCTED
        self.regs[HR_STATUS] = st
        self.regs[HR_STATE] = status.state & 0xFFFF
        self.regs[HR_STEP] = status.step_index & 0xFFFF
        self._write_counters(status)
        speeds = status.conveyor_speeds_mmps
        speed = min(max(speeds[0][1], -0x8000), 0x7FFF) if speeds else 0
        self.regs[HR_CONVEYOR_SPEED] = speed & 0xFFFF  # int16, two's complement


_TRANSIENT_STATES = frozenset(
    {
        PackMLState.CLEARING,
        PackMLState.ABORTING,
        PackMLState.STOPPING,
        PackMLState.RESETTING,
        PackMLState.COMPLETING,
    }
)


def _plc_job_id(result: JobResult) -> int:
    if result.source == SOURCE.name and result.client_job_id.isdigit():
        return int(result.client_job_id) & 0xFFFF
    return 0


#: the requester of a Modbus job: its 16-bit job ids wrap, so they do not name jobs (a PLC's
#: repeated request is caught by the link itself)
SOURCE = JobSource("modbus")


class ModbusServer:
    """The Modbus TCP server of one cell. Construct (no I/O), ``await start()``,
    ``await stop()``; both run on the caller's asyncio loop (a
    :class:`~cellrunner.plc.server.PlcServer`)."""

    name = "modbus"

    def __init__(self, port: CellPort, config: ModbusConfig) -> None:
        self.port = port
        self.config = config
        self.link = ModbusLink(port, config.heartbeat_timeout_s)
        self._server: Any = None
        self._tick_task: asyncio.Task[None] | None = None
        self._remove_listener: Callable[[], None] | None = None

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port), useful with port 0."""
        if self._server is None or self._server.transport is None:
            return (self.config.bind, self.config.port)
        sockname = self._server.transport.sockets[0].getsockname()
        return (sockname[0], sockname[1])

    @property
    def link_up(self) -> bool:
        """The PLC heartbeat (register 0) keeps changing."""
        return self.link.heartbeat_alive

    @property
    def published_at(self) -> str:
        host, port = self.address
        return f"{host}:{port}"

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self.link.restore()
        self._server = tcp_server(self.link, (self.config.bind, self.config.port))
        try:
            await self._server.serve_forever(background=True)
        except (RuntimeError, OSError) as exc:
            self._server = None
            raise CellrunnerError(
                f"cannot listen for Modbus TCP on {self.config.bind}:{self.config.port}: {exc}"
            ) from exc
        self._remove_listener = self.port.add_result_listener(
            lambda result: loop.call_soon_threadsafe(self.link.on_result, result)
        )
        self._tick_task = asyncio.create_task(self._tick_loop(), name="modbus-tick")

    async def stop(self) -> None:
        if self._remove_listener is not None:
            self._remove_listener()
            self._remove_listener = None
        if self._tick_task is not None:
            self._tick_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._tick_task
            self._tick_task = None
        if self._server is not None:
            await self._server.shutdown()
            self._server = None

    async def _tick_loop(self) -> None:
        while True:
            try:
                self.link.tick()
            except Exception:  # the cell engine failed us; keep serving the PLC
                _log.exception("modbus tick failed")
            await asyncio.sleep(TICK_PERIOD_S)
