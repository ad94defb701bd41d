"""The soak bench's PLC program (bench/bench_plc.py) keeps a cell going through every fault
the cell can end a job with: a soak that stalls measures nothing."""

from __future__ import annotations

from bench import bench_plc
from cellrunner.plc.fake import FakeCell
from cellrunner.plc.port import JobResult, ResultCode

HOST = "127.0.4.11"


def test_soak_plc_resets_a_protective_stop_a_job_left_latched_in_idle() -> None:
    """A job that ends with 100 leaves the stop latched: the cell is Idle but never READY
    until the PLC presses RESET. The soak's PLC must press it (it once only reset Aborted
    and Stopped, so the 500-job soak stalled in Idle on the first such job)."""
    cell = FakeCell(results=[0, ResultCode.PROTECTIVE_STOP, 0, 0])

    def latch(result: JobResult) -> None:
        if result.result_code == ResultCode.PROTECTIVE_STOP:
            cell.inject_protective_stop()  # what the twin's arm does: the stop stays

    cell.add_result_listener(latch)
    cell.start()
    try:
        report = bench_plc.run_bench(cell, 4, [[1, 0], [2]], job_timeout_s=5.0, bind=HOST)
    finally:
        cell.close()
    assert report["outcomes"] == {"done": 3, "error": 1}, report["never_ready_in"]
    assert report["reconciliation"]["issues"] == []
    assert [r.result_code for r in cell.finished] == [0, 100, 0, 0]
    assert "reset" in cell.commands
