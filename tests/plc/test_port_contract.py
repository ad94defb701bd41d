"""The PLC servers are tested against FakeCell; this holds FakeCell to the engine: both
answer the same :class:`CellPort` calls the same way (accept, reject codes, busy, refused
commands, the result listener), so a test that passes on the fake means the same on the
real cell."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from cellrunner.model.cellport import CellPort, JobResult
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.plc.fake import FakeCell
from tests.plc.conftest import plc_test_tasks

#: the task both cells know, with an int param ``slot`` in 0-11
TASK, GOOD, BAD = "pick_place", {"slot": 3}, {"slot": 99}


class Engine:
    """The real CellController over a scripted arm, ticked by ``settle``."""

    def __init__(self, tmp_path: Path) -> None:
        from tests.execution.fakes import make_cell

        self.cell, _ = make_cell(tmp_path)

    def settle(self, until: Callable[[], bool], max_ticks: int = 20_000) -> None:
        from tests.execution.fakes import tick

        for _ in range(max_ticks):
            if until():
                return
            if self.cell.planning:
                self.cell.wait_for_plan(timeout_s=1.0)
            tick(self.cell)
        raise AssertionError("the engine did not get there")


class Fake:
    def __init__(self) -> None:
        self.cell = FakeCell(tasks=plc_test_tasks()).start()

    def settle(self, until: Callable[[], bool], max_ticks: int = 2000) -> None:
        import time

        deadline = time.monotonic() + 30
        while not until():
            assert time.monotonic() < deadline, "the fake did not get there"
            time.sleep(0.01)


@pytest.fixture(params=["fake", "engine"])
def rig(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Any]:
    made = Fake() if request.param == "fake" else Engine(tmp_path)
    made.settle(lambda: made.cell.status().ready)
    yield made
    if request.param == "fake":
        made.cell.close()


def test_a_ready_cell_is_idle_and_refuses_what_does_not_apply(rig: Any) -> None:
    port: CellPort = rig.cell
    status = port.status()
    assert status.state == S.IDLE and status.ready and not status.busy
    assert not port.command("unhold") and not port.command("reset")  # nothing held, not done
    with pytest.raises(ValueError, match="unknown command 'jump'"):
        port.command("jump")


def test_rejects_carry_the_code_and_no_job(rig: Any) -> None:
    port: CellPort = rig.cell
    unknown = port.start_job("no_such_task", {}, "c1", "modbus")
    assert (unknown.job_id, unknown.reject_code) == ("", ResultCode.REJECT_UNKNOWN_TASK)
    assert "no_such_task" in unknown.message and not unknown.accepted
    bad = port.start_job(TASK, BAD, "c2", "modbus")
    assert (bad.job_id, bad.reject_code) == ("", ResultCode.REJECT_BAD_PARAMS)
    assert "slot" in bad.message
    assert port.status().ready  # a reject changes nothing


def test_an_accepted_job_makes_the_cell_busy_and_ends_through_the_listener(rig: Any) -> None:
    port: CellPort = rig.cell
    results: list[JobResult] = []
    remove = port.add_result_listener(results.append)
    ticket = port.start_job(TASK, GOOD, "c3", "opcua")
    assert ticket.accepted and ticket.job_id and ticket.reject_code == ResultCode.OK
    assert port.status().busy and not port.status().ready
    second = port.start_job(TASK, GOOD, "c4", "opcua")
    assert second.reject_code == ResultCode.REJECT_NOT_READY
    rig.settle(lambda: bool(results))
    assert [(r.job_id, r.client_job_id, r.source) for r in results] == [
        (ticket.job_id, "c3", "opcua")
    ]
    assert port.status().last_result == results[0]
    # the code travels as the enum; a PLC server makes it a number at the wire
    assert type(results[0].result_code) is ResultCode and results[0].result_code is ResultCode.OK
    assert type(second.reject_code) is ResultCode
    remove()
    rig.settle(lambda: port.status().ready)
    port.start_job(TASK, GOOD, "c5", "opcua")
    rig.settle(lambda: port.status().last_result.client_job_id == "c5")
    assert len(results) == 1  # the removed listener heard nothing more
