"""Alarms for the people on the line: what is wrong now, and what to do about it.

An alarm is raised by the cell's state (e-stop, protective stop, held, aborted), by a
PLC link that is down, or by the last job's result code (SPEC section 7). Each carries
the fix an operator can carry out without opening the logs.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from cellrunner.model.cellport import CellStatus, JobResult
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode

#: what to do after a job ended with each code (OK has none)
FIX: dict[ResultCode, str] = {
    ResultCode.NO_PART: "Check that a part is at the pick frame and that the gripper's closed "
    "sensor switches; the next job runs when the PLC asks.",
    ResultCode.PART_LOST: "Find the dropped part and remove it from the cell; check the jaws, "
    "the grip force and the part's weight.",
    ResultCode.PLACE_FAILED: "Check the place position for an obstacle or a misplaced part; clear "
    "it before the next job.",
    ResultCode.PROTECTIVE_STOP: "Look for what the arm touched and move it clear, then Clear and "
    "Reset (PLC RESET bit).",
    ResultCode.ESTOP: "Make the cell safe and release the emergency stop, then Clear and Reset "
    "(PLC RESET bit).",
    ResultCode.ROBOT_CONNECTION_LOST: "Check that the controller is on, in remote control, and its "
    "network cable; then Clear and Reset.",
    ResultCode.PLANNING_FAILED: "The job could not be planned from where the arm stands: check the "
    "job's parameters and the cell for a moved fixture; run "
    "`cellrunner check` on the task.",
    ResultCode.LIMIT_VIOLATION: "A trajectory broke a joint or speed limit: run `cellrunner check` "
    "on the task and report it; Clear and Reset to continue.",
    ResultCode.STEP_TIMEOUT: "A step did not finish in time: check the input it waited for "
    "(sensor, door, conveyor), then Clear and Reset.",
    ResultCode.ABORTED_BY_PLC: "The PLC aborted the job: find out why on the HMI, then Clear and Reset.",
    ResultCode.INTERRUPTED: "cellrunner restarted during this job: check where the part is and "
    "remove it if needed before the next job.",
    ResultCode.PATH_BLOCKED: "Something the cell file does not list stood in the arm's path (the "
    "journal gives where): take it out of the watched zone, then Clear and Reset.",
}

_STATE_FIX = {
    "estop": "Make the cell safe and release the emergency stop, then Clear and Reset (PLC RESET bit).",
    "protective_stop": "Find what the arm touched and move it clear; the job resumes by itself "
    "after the controller's 5 s unlock delay if the task allows it, "
    "else Clear and Reset.",
    "held": "The cell is held (HOLD from the PLC or its heartbeat stopped): fix the cause, then "
    "UNHOLD from the PLC.",
    "aborted": "Fix the cause shown below, then Clear and Reset (PLC RESET bit).",
    "stopped": "Reset (PLC RESET bit) to bring the cell to Idle.",
    "obstructed": "Take what stands in the watched zone out of the arm's way; the job goes on "
    "by itself once the depth camera sees the path clear (or plans around it, or ends with "
    "108 when it waited as long as the task allows).",
}


@dataclass(frozen=True)
class Alarm:
    """One line on the alarm list: ``severity`` is ``fault`` (the cell cannot run
    jobs), ``warning`` (it needs attention) or ``info``."""

    severity: str
    title: str
    detail: str
    fix: str

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def active_alarms(status: CellStatus, plc_links: dict[str, bool]) -> list[Alarm]:
    """The alarms of ``status`` and the PLC links, most severe first."""
    alarms: list[Alarm] = []
    state = S(status.state)
    if status.estop:
        alarms.append(
            Alarm("fault", "Emergency stop", "The emergency stop is pressed.", _STATE_FIX["estop"])
        )
    if status.protective_stop:
        alarms.append(
            Alarm(
                "fault",
                "Protective stop",
                "The controller stopped the arm (contact or safety limit).",
                _STATE_FIX["protective_stop"],
            )
        )
    if status.obstructed:
        alarms.append(
            Alarm(
                "warning",
                "Obstructed",
                f"The arm waits, stopped on its path, for an obstacle not in the cell file: "
                f"{status.obstruction}.",
                _STATE_FIX["obstructed"],
            )
        )
    if status.held and not status.protective_stop:
        alarms.append(
            Alarm(
                "warning",
                f"Cell {state.display_name}",
                f"The running job is held by {status.hold_source}: {status.hold_reason}."
                if status.hold_source
                else "The running job is held.",
                _STATE_FIX["held"],
            )
        )
    if state in (S.ABORTING, S.ABORTED) and not status.estop:
        alarms.append(
            Alarm(
                "fault",
                f"Cell {state.display_name}",
                _last_text(status.last_result),
                _STATE_FIX["aborted"],
            )
        )
    if state is S.STOPPED:
        alarms.append(
            Alarm("warning", "Cell Stopped", "The cell does not take jobs.", _STATE_FIX["stopped"])
        )
    for name, up in sorted(plc_links.items()):
        if not up:
            alarms.append(
                Alarm(
                    "warning",
                    f"PLC link down ({name})",
                    _LINK_DETAIL.get(name, f"The {name} link has no peer."),
                    _LINK_FIX.get(name, _ANY_LINK_FIX),
                )
            )
    result = status.last_result
    if result is not None and result.result_code != ResultCode.OK:
        code = result.result_code
        severity = "fault" if code.is_fault else "warning"
        alarms.append(
            Alarm(
                severity,
                f"Last job {int(code)}: {code.text}",
                _last_text(result),
                FIX.get(code, ""),
            )
        )
    return alarms


_LINK_DETAIL = {
    "modbus": "The PLC heartbeat (register 0) has not changed within the heartbeat timeout, or no "
    "PLC has written it yet.",
    "opcua": "No OPC UA client is connected.",
}
_LINK_FIX = {
    "modbus": "Check that the PLC program runs and increments register 0, and the network between "
    "PLC and cell; new jobs are refused until the heartbeat moves again.",
    "opcua": "Check that the PLC or SCADA client is running and its certificate and user are "
    "accepted (pki/rejected holds refused certificates).",
}

#: a PLC protocol the texts above do not know yet (a new server): still an alarm, in general
#: words
_ANY_LINK_FIX = (
    "Check that the PLC or client program runs, and the network between it and the cell."
)


def _last_text(result: JobResult | None) -> str:
    if result is None:
        return "No job has run yet."
    task = f" ({result.task})" if result.task else ""
    return f"job {result.job_id}{task}: {result.result_text or result.result_code.text}"
