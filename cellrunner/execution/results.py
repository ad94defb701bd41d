"""Job result codes (SPEC section 7), shared by the journal, the CLI and the PLC link."""

from __future__ import annotations

import enum


class ResultCode(enum.IntEnum):
    OK = 0
    NO_PART = 1
    PART_LOST = 2
    PLACE_FAILED = 3
    REJECTED_UNKNOWN_TASK = 10
    REJECTED_BAD_PARAMS = 11
    REJECTED_NOT_READY = 12
    PROTECTIVE_STOP = 100
    ESTOP = 101
    ROBOT_CONNECTION_LOST = 102
    PLANNING_FAILED = 103
    LIMIT_VIOLATION = 104
    STEP_TIMEOUT = 105
    ABORTED_BY_PLC = 106
    INTERRUPTED = 107

    @property
    def text(self) -> str:
        return _TEXT[self]

    @property
    def is_fault(self) -> bool:
        """Faults abort the cell; NOK results (no part, part lost, place failed) complete."""
        return self >= 100


_TEXT = {
    ResultCode.OK: "OK",
    ResultCode.NO_PART: "no part (grip failed after retries)",
    ResultCode.PART_LOST: "part lost in transit",
    ResultCode.PLACE_FAILED: "place failed",
    ResultCode.REJECTED_UNKNOWN_TASK: "rejected: unknown task",
    ResultCode.REJECTED_BAD_PARAMS: "rejected: bad params",
    ResultCode.REJECTED_NOT_READY: "rejected: not ready",
    ResultCode.PROTECTIVE_STOP: "protective stop not recovered",
    ResultCode.ESTOP: "e-stop",
    ResultCode.ROBOT_CONNECTION_LOST: "robot connection lost",
    ResultCode.PLANNING_FAILED: "planning failed",
    ResultCode.LIMIT_VIOLATION: "limit violation",
    ResultCode.STEP_TIMEOUT: "step timeout",
    ResultCode.ABORTED_BY_PLC: "aborted by PLC",
    ResultCode.INTERRUPTED: "interrupted (cellrunner restarted mid-job)",
}
