"""The one surface the PLC servers drive: :class:`CellPort` (implemented by the engine).

The execution engine implements this Protocol; the Modbus TCP and OPC UA servers in
plc only ever talk to a ``CellPort`` (``FakeCell`` in ``plc/fake.py`` is a
scripted in-process implementation for tests and the soak bench).

Threading contract (the engine must honour it):

* every method may be called from any thread (the PLC servers call from their own
  asyncio thread) and returns within a few milliseconds; ``start_job`` validates,
  journals and queues, it never waits for motion;
* result listeners are called once per finished job, from any thread, *after* the
  counters in :meth:`CellPort.status` already include that job; they must not block;
* ``status()`` is cheap (it is polled every 20 ms).

Result and reject codes are SPEC section 7's; PackML state numbers are section 6's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Protocol, runtime_checkable

from cellrunner.model.codes import PackMLState, ResultCode
from cellrunner.model.failure import Failure
from cellrunner.model.hold_source import HoldSource

__all__ = [
    "COMMANDS",
    "COMPLETED_CODES",
    "REJECT_CODES",
    "SPEC_SOURCES",
    "ArmPort",
    "ArmStatus",
    "CellPort",
    "CellStatus",
    "JobHistory",
    "JobResult",
    "JobSource",
    "JobTicket",
    "PackMLState",
    "ResultCode",
    "ResultListener",
    "TaskCatalog",
]

#: Codes with which a job *completed* (OK or NOK, not a fault): the PLC sees DONE.
COMPLETED_CODES = frozenset(
    {ResultCode.OK, ResultCode.NO_PART, ResultCode.PART_LOST, ResultCode.PLACE_FAILED}
)
#: Codes that reject a job before it starts (JobTicket.reject_code).
REJECT_CODES = frozenset(
    {ResultCode.REJECT_UNKNOWN_TASK, ResultCode.REJECT_BAD_PARAMS, ResultCode.REJECT_NOT_READY}
)

#: Commands accepted by :meth:`CellPort.command`.
COMMANDS = ("reset", "clear", "hold", "unhold", "abort", "stop")


@dataclass(frozen=True)
class JobSource:
    """Who asks for a job: ``name`` is the journal's and the results' ``source``
    (``"modbus"``, ``"opcua"``, ``"cli"``...); ``ids_name_jobs`` says the requester gives
    each job its own client job id and may send a request again, so the same id twice is
    the first job, not a second one (OPC UA's ClientJobId, SPEC 8). A Modbus job id wraps
    at 16 bits and the CLI reuses its labels: theirs do not name jobs."""

    name: str
    ids_name_jobs: bool = False

    @classmethod
    def of(cls, source: str | JobSource) -> JobSource:
        """``source`` as a requester; a plain name is one of :data:`SPEC_SOURCES`, or else a
        requester whose ids do not name jobs."""
        if isinstance(source, JobSource):
            return source
        return SPEC_SOURCES.get(source) or cls(source)


#: the requesters the SPEC defines, for callers that give only their name
SPEC_SOURCES = {s.name: s for s in (JobSource("modbus"), JobSource("opcua", ids_name_jobs=True))}


@dataclass(frozen=True)
class JobResult:
    """How one accepted job ended.

    ``job_id`` is the engine's id (journal key); ``client_job_id`` is what the
    requester gave (the Modbus job id as decimal text, or OPC UA's ClientJobId);
    ``source`` names the requester: ``"modbus"``, ``"opcua"``, ``"cli"``...
    ``end_time`` is timezone-aware UTC; ``cycle_time_s`` in seconds. ``result_code`` is
    the enum everywhere; a PLC server writes its number, at the wire. ``failure`` is
    why a job the planner refused failed, as data (kind, step, blockers, fix; None for
    any other end): the text is ``result_text``.
    """

    job_id: str
    result_code: ResultCode
    result_text: str = ""
    cycle_time_s: float = 0.0
    end_time: datetime | None = None
    retries: int = 0
    task: str = ""
    client_job_id: str = ""
    source: str = ""
    failure: Failure | None = None


@dataclass(frozen=True)
class CellStatus:
    """A snapshot of the cell for the PLC interfaces.

    ``state`` is the PackML StateCurrent number; ``ready`` means a job would be
    accepted now (Idle, no job, no stop active); ``held`` is true in Holding/Held;
    ``job_id`` is the running job's engine id ("" when none) and ``step_index`` its
    current expanded step, 1-based (0 = none). ``last_result`` is the most recently
    finished job, including one closed with 107 at start-up.
    """

    state: int
    state_name: str
    ready: bool
    busy: bool
    held: bool = False
    protective_stop: bool = False
    estop: bool = False
    job_id: str = ""
    step_index: int = 0
    last_result: JobResult | None = None
    parts_processed: int = 0
    parts_defective: int = 0
    #: the arm waits, stopped on its path, for an obstacle of the watched zone (SPEC 12);
    #: ``obstruction`` says where ("" when not obstructed)
    obstructed: bool = False
    obstruction: str = ""
    #: who holds the cell (a :class:`~cellrunner.model.hold_source.HoldSource` value:
    #: ``plc``, ``plc_watchdog``, ``opcua``, ``page``, ``obstacle``, ``protective_stop``)
    #: and why, in words; "" when nothing holds it. An arm waiting for an obstacle is
    #: held by ``obstacle`` (the job goes on once the zone clears)
    hold_source: str = ""
    hold_reason: str = ""
    #: each conveyor's measured speed, mm/s, in the cell file's order (SPEC 13): (name,
    #: speed); none while the backend cannot measure them
    conveyor_speeds_mmps: tuple[tuple[str, int], ...] = ()


@dataclass(frozen=True)
class JobTicket:
    """The immediate answer to :meth:`CellPort.start_job`.

    ``reject_code`` is 0 when the job was accepted (journaled and queued), else 10
    (unknown task), 11 (bad params) or 12 (not ready); ``job_id`` is "" for a reject.
    """

    job_id: str
    reject_code: ResultCode = ResultCode.OK
    message: str = ""

    @property
    def accepted(self) -> bool:
        return self.reject_code == ResultCode.OK


ResultListener = Callable[[JobResult], object]  # what it returns is ignored


@dataclass(frozen=True)
class ArmStatus:
    """The arm as the plant's language describes it (OPC 40010 Robotics, SPEC 13): what
    it is (``model``, the controller's ``serial_number``, "" when unknown), where each
    joint is (``q_rad``, base to wrist 3) and how fast it turns (``qd_rad_s``), the
    controller's safety (``emergency_stop``, ``protective_stop``), and ``task``, the
    name of the task the running job runs ("" when none). ``time_s`` is the controller
    time of the measurement."""

    model: str
    serial_number: str = ""
    manufacturer: str = "Universal Robots"
    controller: str = ""
    q_rad: tuple[float, ...] = ()
    qd_rad_s: tuple[float, ...] = ()
    emergency_stop: bool = False
    protective_stop: bool = False
    task: str = ""
    time_s: float = 0.0


@runtime_checkable
class TaskCatalog(Protocol):
    """What a cell adds to :class:`CellPort` to list what may be ordered: an ISA-95 job
    order's work masters (SPEC 13)."""

    def task_names(self) -> list[str]:
        """The names of the cell's tasks, in PLC task number order."""
        ...


@runtime_checkable
class JobHistory(Protocol):
    """What a cell with a journal adds to :class:`CellPort`: the end of a job a requester
    named, so an ISA-95 job order answers after a restart (SPEC 13)."""

    def finished_job(self, source: str, client_job_id: str) -> JobResult | None:
        """How the job ``source`` named ``client_job_id`` ended; None when no such job
        has ended. Reads the journal: a few milliseconds, from any thread."""
        ...


@runtime_checkable
class ArmPort(Protocol):
    """What a cell that can describe its arm adds to :class:`CellPort`; the OPC UA
    server's Robotics objects read it (a port without it shows no arm)."""

    def arm(self) -> ArmStatus:
        """The arm's last measurement; cheap, non-blocking, from any thread."""
        ...


@runtime_checkable
class CellPort(Protocol):
    """What the PLC servers need from the cell engine."""

    def status(self) -> CellStatus:
        """The current snapshot (cheap, non-blocking)."""
        ...

    def task_params(self, task: str | int) -> list[str] | None:
        """The task's parameter names in its ``params:`` order; None if unknown.

        ``task`` is a PLC task number (cell file ``tasks:``) or a task name.
        """
        ...

    def start_job(
        self,
        task: str | int,
        params: dict[str, Any],  # numbers, quantities ("250 ms"), poses
        client_job_id: str,
        source: str | JobSource,
    ) -> JobTicket:
        """Validate, journal and queue one job; never blocks on motion. ``source`` is the
        requester (a plain name: :meth:`JobSource.of`); when its ids name jobs, a
        ``client_job_id`` already journaled answers with that job's ticket.

        Rejects: 10 unknown task, 11 params outside the task's typed bounds (or
        unknown names), 12 not ready (not Idle, job running, stop active).
        """
        ...

    def command(self, name: str, source: HoldSource = HoldSource.PLC) -> bool:
        """A PackML command: one of :data:`COMMANDS`, asked by ``source`` (who holds, for
        a hold: the PLC, its watchdog, an operator over OPC UA or on the status page).

        Returns False (and does nothing) when the command is not valid in the
        current state; never raises for that. An unknown name raises ValueError.
        """
        ...

    def add_result_listener(self, listener: ResultListener) -> Callable[[], None]:
        """Call ``listener(result)`` for every job that finishes from now on.

        Returns a function that removes the listener.
        """
        ...
