"""ISA-95 job orders (OPC 10031-4, as OPC 40001-3 Machinery Job Management uses it): the
book of the orders an MES sent, their states, and the cell's jobs that run them.

This module is the behaviour, with no OPC UA in it; :mod:`cellrunner.plc.opcua_jobs`
puts it in the address space. All its methods run on the OPC UA server's thread.

An order names a task (its first work master's ID, or a parameter ``Task``) and the
task's params (the other job order parameters). Its JobOrderID is the job's ClientJobId
(SPEC 13): the same order sent again is the same order, and after a restart the journal
answers it with the first job (:class:`~cellrunner.model.cellport.JobSource`).

States (the standard's numbers)::

    Store          -> NotAllowedToStart (1) / Ready (2)
    StoreAndStart  -> AllowedToStart (2) / Ready (2)     Start moves 1 to 2
    the cell takes the oldest allowed order of the highest priority when it is ready
                   -> Running (3)
    the cell holds its job          -> Interrupted (4) / Held (1), back to Running
    the job completes (OK or NOK)   -> Ended (5) / Completed (1)
    the job faults, Abort           -> Aborted (6)
    Clear removes an Ended or Aborted order from the list (its response stays).
    RevokeStart moves 2 back to 1; Cancel aborts an order that has not started; Pause and
    Resume hold and unhold the cell while the order runs.
"""

from __future__ import annotations

import enum
import itertools
import json
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from typing import Any

from cellrunner.model.cellport import (
    COMPLETED_CODES,
    CellPort,
    CellStatus,
    JobHistory,
    JobResult,
    JobSource,
    ResultCode,
)


class OrderState(enum.IntEnum):
    """ISA95JobOrderReceiverObjectType's states and their StateNumbers."""

    NOT_ALLOWED_TO_START = 1
    ALLOWED_TO_START = 2
    RUNNING = 3
    INTERRUPTED = 4
    ENDED = 5
    ABORTED = 6


#: the sub-state machines' states by their StateNumbers: prepare (NotAllowedToStart and
#: AllowedToStart), interrupted, ended
PREPARE_READY = ("Ready", 2)
INTERRUPTED_HELD = ("Held", 1)
ENDED_COMPLETED = ("Completed", 1)
SUBSTATE = {
    OrderState.NOT_ALLOWED_TO_START: PREPARE_READY,
    OrderState.ALLOWED_TO_START: PREPARE_READY,
    OrderState.INTERRUPTED: INTERRUPTED_HELD,
    OrderState.ENDED: ENDED_COMPLETED,
}

#: the names the standard gives the states (BrowseNames of the state objects)
STATE_NAMES = {
    OrderState.NOT_ALLOWED_TO_START: "NotAllowedToStart",
    OrderState.ALLOWED_TO_START: "AllowedToStart",
    OrderState.RUNNING: "Running",
    OrderState.INTERRUPTED: "Interrupted",
    OrderState.ENDED: "Ended",
    OrderState.ABORTED: "Aborted",
}


class ReturnStatus(enum.IntFlag):
    """The methods' ReturnStatus (OPC 10031-4 annex B: a UInt64 bit map)."""

    NO_ERROR = 1 << 0
    UNKNOWN_JOB_ORDER_ID = 1 << 1
    INVALID_JOB_ORDER_COMMAND = 1 << 2
    INVALID_JOB_ORDER_STATUS = 1 << 3
    UNABLE_TO_ACCEPT_JOB_ORDER = 1 << 4
    INVALID_REQUEST = 1 << 32


#: orders stored and not ended at once (the MaxDownloadableJobOrders the cell announces)
MAX_OPEN_ORDERS = 100
#: ended and aborted orders remembered (list and responses); older ones are forgotten
MAX_ENDED_ORDERS = 200
#: the longest JobOrderID (the ClientJobId's bound, SPEC 8)
MAX_ORDER_ID = 128
#: the parameter IDs that name the task instead of the work master
TASK_PARAMETERS = ("Task", "TaskName")


@dataclass(frozen=True)
class OrderRequest:
    """What an MES asks for in a job order: ``order_id`` (JobOrderID), the ``task`` (a
    name or a PLC task number), its ``params``, the order's ``priority`` (higher first)
    and ``original``, the client's structure, shown back as it came."""

    order_id: str
    task: str | int
    params: dict[str, Any]
    priority: int = 0
    original: Any = None


@dataclass
class JobOrder:
    """One order in the book, with its state and, once the cell ran it, its job."""

    request: OrderRequest
    state: OrderState
    seq: int
    job_id: str = ""
    start_time: datetime | None = None
    end_time: datetime | None = None
    result: JobResult | None = None
    abort_requested: bool = False

    @property
    def order_id(self) -> str:
        return self.request.order_id

    @property
    def substate(self) -> tuple[str, int] | None:
        return SUBSTATE.get(self.state)

    def at(self, state: OrderState) -> JobOrder:
        """This order as it was in ``state`` (for an event about that state)."""
        return replace(self, state=state)

    @property
    def finished(self) -> bool:
        return self.state in (OrderState.ENDED, OrderState.ABORTED)


def parse_request(
    order_id: str,
    work_masters: list[str],
    parameters: list[tuple[str, Any]],
    priority: int | None,
    original: Any = None,
) -> OrderRequest | str:
    """An :class:`OrderRequest` from a job order's fields, or why it cannot be one: the
    task is the first work master's ID, or a parameter named in :data:`TASK_PARAMETERS`;
    a parameter's value is a number, a text quantity ("250 ms") or a pose as JSON text."""
    if not order_id or len(order_id) > MAX_ORDER_ID:
        return f"JobOrderID must have 1 to {MAX_ORDER_ID} characters"
    params: dict[str, Any] = {}
    task: str | int | None = work_masters[0] if work_masters and work_masters[0] else None
    for name, value in parameters:
        if name in TASK_PARAMETERS:
            task = value if isinstance(value, int | str) and not isinstance(value, bool) else None
            continue
        if name in params:
            return f"parameter {name!r} given twice"
        if isinstance(value, str) and value.lstrip().startswith("{"):
            try:
                value = json.loads(value)
            except ValueError:
                return f"parameter {name!r}: {value!r} is not a pose in JSON"
        if isinstance(value, bool) or not isinstance(value, int | float | str | dict):
            return f"parameter {name!r}: a {type(value).__name__} is no param value"
        params[name] = value
    if task is None or task == "":
        return "no task: give it as the first work master's ID or as a parameter 'Task'"
    if isinstance(task, str) and task.strip().isdigit():
        task = int(task)
    return OrderRequest(order_id, task, params, priority or 0, original)


@dataclass
class OrderBook:
    """The job orders of one cell and their states; :meth:`take_changes` gives each
    state an order entered since it was last called (one status event each)."""

    port: CellPort
    source: JobSource
    clock: Any = field(default=lambda: datetime.now(UTC))
    orders: OrderedDict[str, JobOrder] = field(default_factory=OrderedDict)
    #: ended orders Clear removed from the list; their responses are still answered
    cleared: OrderedDict[str, JobOrder] = field(default_factory=OrderedDict)
    _seq: Any = field(default_factory=lambda: itertools.count(1))
    _changed: list[tuple[JobOrder, OrderState]] = field(default_factory=list)

    # -- the methods ---------------------------------------------------------------
    def store(self, request: OrderRequest, *, start: bool) -> ReturnStatus:
        """Store (and, with ``start``, allow to start) an order; the same JobOrderID again
        is the stored order (its state unchanged, or started if it waited)."""
        known = self.find(request.order_id)
        if known is not None:
            if start and known.state is OrderState.NOT_ALLOWED_TO_START:
                self._move(known, OrderState.ALLOWED_TO_START)
            return ReturnStatus.NO_ERROR
        if self.port.task_params(request.task) is None:
            return ReturnStatus.UNABLE_TO_ACCEPT_JOB_ORDER
        if sum(not o.finished for o in self.orders.values()) >= MAX_OPEN_ORDERS:
            return ReturnStatus.UNABLE_TO_ACCEPT_JOB_ORDER
        state = OrderState.ALLOWED_TO_START if start else OrderState.NOT_ALLOWED_TO_START
        order = JobOrder(request, state, next(self._seq))
        self.orders[request.order_id] = order
        self._changed.append((order, state))
        self._forget_old()
        return ReturnStatus.NO_ERROR

    def start(self, order_id: str) -> ReturnStatus:
        order = self.orders.get(order_id)
        if order is None:
            return ReturnStatus.UNKNOWN_JOB_ORDER_ID
        if order.state is OrderState.ALLOWED_TO_START:
            return ReturnStatus.NO_ERROR  # asked twice: it is allowed
        if order.state is not OrderState.NOT_ALLOWED_TO_START:
            return ReturnStatus.INVALID_JOB_ORDER_STATUS
        self._move(order, OrderState.ALLOWED_TO_START)
        return ReturnStatus.NO_ERROR

    def abort(self, order_id: str) -> ReturnStatus:
        """An order not started yet is aborted now; a running one's job is aborted on the
        cell (the order is Aborted when its result comes)."""
        order = self.orders.get(order_id)
        if order is None:
            return ReturnStatus.UNKNOWN_JOB_ORDER_ID
        if order.state in (OrderState.NOT_ALLOWED_TO_START, OrderState.ALLOWED_TO_START):
            order.end_time = self.clock()
            self._move(order, OrderState.ABORTED)
            return ReturnStatus.NO_ERROR
        if order.finished:
            return ReturnStatus.INVALID_JOB_ORDER_STATUS
        if order.abort_requested or self.port.command("abort"):
            order.abort_requested = True
            return ReturnStatus.NO_ERROR
        return ReturnStatus.INVALID_JOB_ORDER_COMMAND

    def revoke_start(self, order_id: str) -> ReturnStatus:
        """An allowed order that has not started is no longer allowed to start."""
        return self._if_state(
            order_id, OrderState.ALLOWED_TO_START, OrderState.NOT_ALLOWED_TO_START
        )

    def cancel(self, order_id: str) -> ReturnStatus:
        """An order that has not started is aborted (a running one needs Abort)."""
        order = self.orders.get(order_id)
        if order is not None and order.state in (
            OrderState.NOT_ALLOWED_TO_START,
            OrderState.ALLOWED_TO_START,
        ):
            return self.abort(order_id)
        return (
            ReturnStatus.UNKNOWN_JOB_ORDER_ID
            if order is None
            else ReturnStatus.INVALID_JOB_ORDER_STATUS
        )

    def pause(self, order_id: str) -> ReturnStatus:
        """Hold the cell while this order runs (it becomes Interrupted/Held)."""
        return self._command_while(order_id, OrderState.RUNNING, "hold")

    def resume(self, order_id: str) -> ReturnStatus:
        """Unhold the cell for this interrupted order."""
        return self._command_while(order_id, OrderState.INTERRUPTED, "unhold")

    def _if_state(self, order_id: str, now: OrderState, then: OrderState) -> ReturnStatus:
        order = self.orders.get(order_id)
        if order is None:
            return ReturnStatus.UNKNOWN_JOB_ORDER_ID
        if order.state is not now:
            return ReturnStatus.INVALID_JOB_ORDER_STATUS
        self._move(order, then)
        return ReturnStatus.NO_ERROR

    def _command_while(self, order_id: str, state: OrderState, command: str) -> ReturnStatus:
        order = self.orders.get(order_id)
        if order is None:
            return ReturnStatus.UNKNOWN_JOB_ORDER_ID
        if order.state is not state:
            return ReturnStatus.INVALID_JOB_ORDER_STATUS
        if not self.port.command(command):
            return ReturnStatus.INVALID_JOB_ORDER_COMMAND
        return ReturnStatus.NO_ERROR

    def clear(self, order_id: str) -> ReturnStatus:
        order = self.orders.get(order_id)
        if order is None:
            return ReturnStatus.UNKNOWN_JOB_ORDER_ID
        if not order.finished:
            return ReturnStatus.INVALID_JOB_ORDER_STATUS
        del self.orders[order_id]
        self.cleared[order_id] = order
        while len(self.cleared) > MAX_ENDED_ORDERS:
            self.cleared.popitem(last=False)
        return ReturnStatus.NO_ERROR

    # -- following the cell ----------------------------------------------------------
    def follow(self, status: CellStatus) -> None:
        """Follow the cell's status (every refresh): running orders held or going on, and
        the next allowed order started when the cell is ready."""
        for order in list(self.orders.values()):
            if not order.job_id or order.finished:
                continue
            if order.job_id == status.job_id:
                wanted = OrderState.INTERRUPTED if status.held else OrderState.RUNNING
                if order.state is not wanted:
                    self._move(order, wanted)
            elif not status.busy and (done := self._history(order.order_id)) is not None:
                self._end(order, done)  # it ended while no listener heard (a restart)
        if status.ready and not any(o.state is OrderState.RUNNING for o in self.orders.values()):
            self._start_next(status)

    def finish(self, result: JobResult) -> None:
        """A job ended: its order (found by job id) is Ended or Aborted."""
        for order in self.orders.values():
            if order.job_id == result.job_id and not order.finished:
                self._end(order, result)
                return

    def _start_next(self, status: CellStatus) -> None:
        waiting = [o for o in self.orders.values() if o.state is OrderState.ALLOWED_TO_START]
        if not waiting:
            return
        order = min(waiting, key=lambda o: (-o.request.priority, o.seq))
        request = order.request
        ticket = self.port.start_job(request.task, request.params, request.order_id, self.source)
        if not ticket.accepted:
            if ticket.reject_code == ResultCode.REJECT_NOT_READY:
                return  # another requester's job came first: try again at the next refresh
            now = self.clock()
            order.start_time = order.end_time = now
            self._end(order, _rejected(order, ticket.reject_code, ticket.message, now))
            return
        order.job_id, order.start_time = ticket.job_id, self.clock()
        self._move(order, OrderState.RUNNING)
        done = self._history(request.order_id) or status.last_result
        if done is not None and done.job_id == ticket.job_id:  # a job the journal had ended
            self._end(order, done)

    def _end(self, order: JobOrder, result: JobResult) -> None:
        order.result = result
        order.end_time = result.end_time or self.clock()
        completed = result.result_code in COMPLETED_CODES
        self._move(order, OrderState.ENDED if completed else OrderState.ABORTED)

    def _move(self, order: JobOrder, state: OrderState) -> None:
        order.state = state
        self._changed.append((order, state))

    def _forget_old(self) -> None:
        ended = [key for key, o in self.orders.items() if o.finished]
        for key in ended[: max(0, len(ended) - MAX_ENDED_ORDERS)]:
            del self.orders[key]

    # -- reading -----------------------------------------------------------------------
    def find(self, order_id: str) -> JobOrder | None:
        """The order of that JobOrderID: in the book, cleared, or one the journal ran
        before a restart (then put back in the book, Ended or Aborted)."""
        known = self.orders.get(order_id) or self.cleared.get(order_id)
        if known is not None or not order_id:
            return known
        done = self._history(order_id)
        if done is None:
            return None
        request = OrderRequest(order_id, done.task, {})
        order = JobOrder(request, OrderState.RUNNING, next(self._seq), job_id=done.job_id)
        self.orders[order_id] = order
        self._end(order, done)
        return order

    def _history(self, order_id: str) -> JobResult | None:
        port = self.port
        return (
            port.finished_job(self.source.name, order_id) if isinstance(port, JobHistory) else None
        )

    def in_state(self, wanted: list[tuple[int, int | None]]) -> list[JobOrder]:
        """The orders (cleared ones included) in one of the ``wanted`` (state, sub-state)
        numbers; a sub-state of None matches any."""
        found = []
        for order in itertools.chain(self.orders.values(), self.cleared.values()):
            sub = order.substate
            for state, substate in wanted:
                if state == order.state and (substate is None or (sub and sub[1] == substate)):
                    found.append(order)
                    break
        return found

    def take_changes(self) -> list[tuple[JobOrder, OrderState]]:
        changed, self._changed = self._changed, []
        return changed


def _rejected(order: JobOrder, code: ResultCode, message: str, now: datetime) -> JobResult:
    return JobResult(
        order.job_id,
        ResultCode(code),
        message,
        0.0,
        now,
        task=str(order.request.task),
        client_job_id=order.order_id,
    )
