"""ISA-95 job orders' behaviour (cellrunner.plc.job_orders) on a FakeCell: which order runs
next, what a hold and a refused param do to an order, and what survives a restart."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from cellrunner.plc.fake import FakeCell
from cellrunner.plc.job_orders import OrderBook, OrderRequest, OrderState, ReturnStatus
from cellrunner.plc.opcua import SOURCE
from tests.plc.conftest import plc_test_tasks


@pytest.fixture
def cell() -> Iterator[FakeCell]:
    with FakeCell(tasks=plc_test_tasks()) as fake:
        yield fake


def follow_until(book: OrderBook, cell: FakeCell, done: object, timeout_s: float = 10.0) -> None:
    """Follow the cell every 20 ms (as the server does every 50 ms) until ``done()``."""
    deadline = time.monotonic() + timeout_s
    while not done():  # type: ignore[operator]
        assert time.monotonic() < deadline, [(o.order_id, o.state) for o in book.orders.values()]
        book.follow(cell.status())
        for result in cell.finished:
            book.finish(result)
        time.sleep(0.02)


def test_the_highest_priority_then_the_oldest_order_runs_first(cell: FakeCell) -> None:
    book = OrderBook(cell, SOURCE)
    assert cell.start_job("slow", {}, "7", "modbus").accepted  # the cell is busy
    for order_id, priority in (("low-1", 0), ("high", 5), ("low-2", 0)):
        status = book.store(OrderRequest(order_id, "home", {}, priority), start=True)
        assert status is ReturnStatus.NO_ERROR
    follow_until(book, cell, lambda: all(o.finished for o in book.orders.values()), 20)
    ran = [r.client_job_id for r in cell.finished if r.source == "opcua"]
    assert ran == ["high", "low-1", "low-2"]
    assert [o.state for o in book.orders.values()] == [OrderState.ENDED] * 3


def test_a_held_job_interrupts_its_order_and_refused_params_abort_one(cell: FakeCell) -> None:
    book = OrderBook(cell, SOURCE)
    book.store(OrderRequest("slow-1", "slow", {}), start=True)
    order = book.orders["slow-1"]
    follow_until(book, cell, lambda: order.state is OrderState.RUNNING)
    assert cell.command("hold")
    follow_until(book, cell, lambda: order.state is OrderState.INTERRUPTED)
    assert order.substate == ("Held", 1)
    assert cell.command("unhold")
    follow_until(book, cell, lambda: order.finished, 20)
    states = [state for o, state in book.take_changes() if o is order]
    assert OrderState.INTERRUPTED in states and states[-1] is OrderState.ENDED
    book.store(OrderRequest("bad", "pick_place", {"slot": 99}), start=True)
    follow_until(book, cell, lambda: book.orders["bad"].finished)
    bad = book.orders["bad"]
    assert bad.state is OrderState.ABORTED and bad.result is not None
    assert bad.result.result_code == 11  # bad params, as StartJob's reject code


def test_an_order_the_cell_ran_before_a_restart_is_answered_and_not_run_again(
    cell: FakeCell,
) -> None:
    first = OrderBook(cell, SOURCE)
    first.store(OrderRequest("WO-9", "home", {}), start=True)
    follow_until(first, cell, lambda: first.orders["WO-9"].finished)
    job_id = first.orders["WO-9"].job_id
    again = OrderBook(cell, SOURCE)  # a new server on the same cell (and journal)
    recovered = again.find("WO-9")
    assert recovered is not None and recovered.state is OrderState.ENDED
    assert recovered.job_id == job_id and recovered.result is not None
    assert again.store(OrderRequest("WO-9", "home", {}), start=True) is ReturnStatus.NO_ERROR
    again.follow(cell.status())
    assert [r.job_id for r in cell.finished if r.client_job_id == "WO-9"] == [job_id]
    assert again.find("never-sent") is None
    assert again.start("never-sent") is ReturnStatus.UNKNOWN_JOB_ORDER_ID


def test_a_job_orders_task_and_params_are_read_as_the_standard_carries_them() -> None:
    from cellrunner.plc.job_orders import parse_request

    by_work_master = parse_request("A", ["pick_place"], [("slot", 3)], 2)
    assert by_work_master == OrderRequest("A", "pick_place", {"slot": 3}, 2)
    by_parameter = parse_request("B", [], [("Task", "1"), ("at", '{"xyz": [0.1, 0, 0]}')], None)
    assert by_parameter == OrderRequest("B", 1, {"at": {"xyz": [0.1, 0, 0]}}, 0)
    assert parse_request("C", [], [("slot", 1)], None) == (
        "no task: give it as the first work master's ID or as a parameter 'Task'"
    )
    assert parse_request("D", ["home"], [("a", 1), ("a", 2)], None) == "parameter 'a' given twice"
    assert parse_request("", ["home"], [], None) == "JobOrderID must have 1 to 128 characters"
    assert parse_request("E", ["home"], [("on", True)], None) == (
        "parameter 'on': a bool is no param value"
    )


def test_revoke_cancel_pause_and_resume_act_only_in_their_states(cell: FakeCell) -> None:
    book = OrderBook(cell, SOURCE)
    assert book.store(OrderRequest("R", "slow", {}), start=True) is ReturnStatus.NO_ERROR
    assert book.revoke_start("R") is ReturnStatus.NO_ERROR
    assert book.orders["R"].state is OrderState.NOT_ALLOWED_TO_START
    assert book.revoke_start("R") is ReturnStatus.INVALID_JOB_ORDER_STATUS
    assert book.pause("R") is ReturnStatus.INVALID_JOB_ORDER_STATUS  # not running
    book.follow(cell.status())  # not allowed: it does not start
    assert not book.orders["R"].job_id
    assert book.cancel("R") is ReturnStatus.NO_ERROR
    assert book.orders["R"].state is OrderState.ABORTED
    assert book.cancel("R") is ReturnStatus.INVALID_JOB_ORDER_STATUS
    book.store(OrderRequest("P", "slow", {}), start=True)
    order = book.orders["P"]
    follow_until(book, cell, lambda: order.state is OrderState.RUNNING)
    assert book.cancel("P") is ReturnStatus.INVALID_JOB_ORDER_STATUS  # running: Abort it
    assert book.pause("P") is ReturnStatus.NO_ERROR
    follow_until(book, cell, lambda: order.state is OrderState.INTERRUPTED)
    assert book.resume("P") is ReturnStatus.NO_ERROR
    follow_until(book, cell, lambda: order.finished, 20)
    assert order.state is OrderState.ENDED and cell.commands[-2:] == ["hold", "unhold"]
    assert book.resume("nope") is ReturnStatus.UNKNOWN_JOB_ORDER_ID


def test_an_order_for_an_unknown_task_or_beyond_the_open_orders_is_not_accepted(
    cell: FakeCell,
) -> None:
    from cellrunner.plc.job_orders import MAX_OPEN_ORDERS

    book = OrderBook(cell, SOURCE)
    refused = book.store(OrderRequest("U", "nope", {}), start=True)
    assert refused is ReturnStatus.UNABLE_TO_ACCEPT_JOB_ORDER and "U" not in book.orders
    for i in range(MAX_OPEN_ORDERS):
        assert book.store(OrderRequest(f"O{i}", "home", {}), start=False) is ReturnStatus.NO_ERROR
    over = book.store(OrderRequest("one-more", "home", {}), start=False)
    assert over is ReturnStatus.UNABLE_TO_ACCEPT_JOB_ORDER
    assert book.cancel("O0") is ReturnStatus.NO_ERROR  # an aborted order is no longer open
    assert book.store(OrderRequest("one-more", "home", {}), start=False) is ReturnStatus.NO_ERROR
