"""The contract's numbers: PackML states (SPEC section 6) and job result codes (section 7).

Shared by the engine, the journal, the CLI and both PLC servers; pure data.
"""

from __future__ import annotations

import enum


class PackMLState(enum.IntEnum):
    """PackML StateCurrent numbers (SPEC section 6)."""

    CLEARING = 1
    STOPPED = 2
    STARTING = 3
    IDLE = 4
    SUSPENDED = 5
    EXECUTE = 6
    STOPPING = 7
    ABORTING = 8
    ABORTED = 9
    HOLDING = 10
    HELD = 11
    UNHOLDING = 12
    SUSPENDING = 13
    UNSUSPENDING = 14
    RESETTING = 15
    COMPLETING = 16
    COMPLETE = 17

    @property
    def display_name(self) -> str:
        """``Execute``, ``Held``... as PackML tools show the state."""
        return self.name.capitalize()


class ResultCode(enum.IntEnum):
    OK = 0
    NO_PART = 1
    PART_LOST = 2
    PLACE_FAILED = 3
    REJECT_UNKNOWN_TASK = 10
    REJECT_BAD_PARAMS = 11
    REJECT_NOT_READY = 12
    PROTECTIVE_STOP = 100
    ESTOP = 101
    ROBOT_CONNECTION_LOST = 102
    PLANNING_FAILED = 103
    LIMIT_VIOLATION = 104
    STEP_TIMEOUT = 105
    ABORTED_BY_PLC = 106
    INTERRUPTED = 107
    PATH_BLOCKED = 108
    PART_LEFT_WINDOW = 109

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
    ResultCode.REJECT_UNKNOWN_TASK: "rejected: unknown task",
    ResultCode.REJECT_BAD_PARAMS: "rejected: bad params",
    ResultCode.REJECT_NOT_READY: "rejected: not ready",
    ResultCode.PROTECTIVE_STOP: "protective stop not recovered",
    ResultCode.ESTOP: "e-stop",
    ResultCode.ROBOT_CONNECTION_LOST: "robot connection lost",
    ResultCode.PLANNING_FAILED: "planning failed",
    ResultCode.LIMIT_VIOLATION: "limit violation",
    ResultCode.STEP_TIMEOUT: "step timeout",
    ResultCode.ABORTED_BY_PLC: "aborted by PLC",
    ResultCode.INTERRUPTED: "interrupted (cellrunner restarted mid-job)",
    ResultCode.PATH_BLOCKED: "path blocked by an obstacle not in the cell file",
    ResultCode.PART_LEFT_WINDOW: "part left the conveyor window",
}
