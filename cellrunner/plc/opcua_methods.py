"""The methods of ``Objects/Cell`` (SPEC 8): StartJob(TaskName, Parameters JSON, ClientJobId)
-> (JobId, ReturnCode), and Reset() Hold() Unhold() Abort() Clear() Stop(); their arguments
checked (StartJob's strings bounded by :data:`~cellrunner.plc.opcua_config.MAX_TEXT`,
reject code 11), then the :class:`~cellrunner.plc.port.CellPort` called."""

from __future__ import annotations

import json
import logging
import math
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

from cellrunner.model.hold_source import HoldSource
from cellrunner.model.params import ParamValue
from cellrunner.plc.opcua_config import (
    MAX_INT_DIGITS,
    MAX_JSON_DEPTH,
    MAX_REMEMBERED_CLIENT_JOBS,
    MAX_TEXT,
)
from cellrunner.plc.opcua_ua import argument, node_id, status_code
from cellrunner.plc.port import CellPort, JobSource, ResultCode

_log = logging.getLogger(__name__)

#: browse name of each command method, and the port's command it calls
COMMAND_METHODS = {
    "Reset": "reset",
    "Hold": "hold",
    "Unhold": "unhold",
    "Abort": "abort",
    "Clear": "clear",
    "Stop": "stop",
}


class CellMethods:
    """StartJob and the commands, for one port; StartJob is idempotent per ClientJobId."""

    def __init__(self, port: CellPort, source: JobSource) -> None:
        self.port = port
        self.source = source
        self._client_jobs: OrderedDict[str, tuple[str, int]] = OrderedDict()

    async def add_to(self, cell: Any, idx: int) -> None:
        """Declare the methods on the ``Cell`` object (namespace index ``idx``)."""
        from asyncua import ua

        string, int32 = ua.VariantType.String, ua.VariantType.Int32
        await cell.add_method(
            node_id("Cell.StartJob", idx),
            ua.QualifiedName("StartJob", idx),
            self.start_job_method,
            [
                argument("TaskName", string, "task name or PLC task number"),
                argument("Parameters", string, "JSON object of task params"),
                argument("ClientJobId", string, "caller's id; the same id returns the first job"),
            ],
            [
                argument("JobId", string, "the cell's job id"),
                argument("ReturnCode", int32, "0 accepted, else reject code 10/11/12"),
            ],
        )
        for name, command in COMMAND_METHODS.items():
            await cell.add_method(
                node_id(f"Cell.{name}", idx),
                ua.QualifiedName(name, idx),
                self.command_method(command),
                [],
                [],
            )

    async def start_job_method(self, parent: Any, *args: Any) -> Any:
        from asyncua import ua

        if len(args) != 3:
            return status_code(
                ua.status_codes.StatusCodes.BadArgumentsMissing
                if len(args) < 3
                else ua.status_codes.StatusCodes.BadTooManyArguments
            )
        if all(_is_string(a) for a in args):
            task_name, params_text, client_job_id = (_text(a) for a in args)
            job_id, code = self.start_job(task_name, params_text, client_job_id)
        else:  # a Null variant or another type: bad params, as a PLC reads a ReturnCode
            _log.warning("StartJob refused: arguments %s, not 3 Strings", _type_names(args))
            job_id, code = "", int(ResultCode.REJECT_BAD_PARAMS)
        return [ua.Variant(job_id, ua.VariantType.String), ua.Variant(code, ua.VariantType.Int32)]

    def start_job(self, task_name: str, params_text: str, client_job_id: str) -> tuple[str, int]:
        """StartJob's logic: (JobId, ReturnCode); idempotent per non-empty ClientJobId.
        Over-long strings are refused with 11 (bad params) before anything else."""
        for name, text in (
            ("TaskName", task_name),
            ("Parameters", params_text),
            ("ClientJobId", client_job_id),
        ):
            if len(text) > MAX_TEXT[name]:
                _log.warning(
                    "StartJob refused: %s of %d characters (at most %d)",
                    name,
                    len(text),
                    MAX_TEXT[name],
                )
                return "", int(ResultCode.REJECT_BAD_PARAMS)
        if client_job_id and client_job_id in self._client_jobs:
            return self._client_jobs[client_job_id]
        params = parse_job_parameters(params_text)
        if params is None:
            return "", int(ResultCode.REJECT_BAD_PARAMS)
        task: str | int = int(task_name) if task_name.strip().isdigit() else task_name.strip()
        ticket = self.port.start_job(task, params, client_job_id, self.source)
        if not ticket.accepted:
            return "", int(ticket.reject_code or ResultCode.REJECT_NOT_READY)  # the wire
        if client_job_id:
            self._client_jobs[client_job_id] = (ticket.job_id, int(ResultCode.OK))
            while len(self._client_jobs) > MAX_REMEMBERED_CLIENT_JOBS:
                self._client_jobs.popitem(last=False)
        return ticket.job_id, int(ResultCode.OK)

    def command_method(self, command: str) -> Callable[..., Any]:
        async def call(parent: Any, *args: Any) -> Any:
            from asyncua import ua

            if args:
                return status_code(ua.status_codes.StatusCodes.BadTooManyArguments)
            if not self.port.command(command, HoldSource.OPCUA):
                return status_code(ua.status_codes.StatusCodes.BadInvalidState)
            return []

        return call


def _refuse_constant(name: str) -> float:
    # ValueError: json.loads's parse_constant contract (its caller catches it)
    raise ValueError(f"{name} is not a number JSON allows")


def parse_job_parameters(text: str) -> dict[str, ParamValue | str] | None:
    """StartJob's Parameters: a JSON object of finite numbers, quantities with a unit
    ("250 ms") and poses ({"xyz": [m], "rpy": [deg]}) (empty text = {}); None if not
    (also for NaN/Infinity, integers of more than MAX_INT_DIGITS digits, over-long text, or
    nesting deeper than an object of poses, which is refused before it is parsed)."""
    if not text or not text.strip():
        return {}
    if len(text) > MAX_TEXT["Parameters"] or _nesting(text) > MAX_JSON_DEPTH:
        return None
    try:
        data = json.loads(text, parse_constant=_refuse_constant, parse_int=_bounded_int)
    except (ValueError, RecursionError):
        return None
    if not isinstance(data, dict):
        return None
    params: dict[str, ParamValue | str] = {}
    for name, value in data.items():
        if isinstance(value, dict):
            if not set(value) <= {"xyz", "rpy"} or not all(
                isinstance(v, list)
                and all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
                for v in value.values()
            ):
                return None
        elif isinstance(value, bool) or not isinstance(value, int | float | str):
            return None
        if isinstance(value, float) and not math.isfinite(value):
            return None
        params[str(name)] = value
    return params


def _bounded_int(text: str) -> int:
    """A JSON integer that a param can hold (int64 at most; a 1000-digit one is refused)."""
    if len(text.lstrip("-")) > MAX_INT_DIGITS:  # ValueError: json.loads's parse_int contract
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def _nesting(text: str) -> int:
    """The deepest bracket nesting in ``text`` (strings counted too: an upper bound)."""
    depth = deepest = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _is_string(argument: Any) -> bool:
    """A String variant (asyncua passes Variants; a plain str from in-process calls)."""
    from asyncua import ua

    if isinstance(argument, ua.Variant):
        return argument.VariantType == ua.VariantType.String and (
            argument.Value is None or isinstance(argument.Value, str)
        )
    return isinstance(argument, str)


def _type_names(args: tuple[Any, ...]) -> str:
    return ", ".join(
        a.VariantType.name if hasattr(a, "VariantType") else type(a).__name__ for a in args
    )


def _text(variant: Any) -> str:
    value = getattr(variant, "Value", variant)
    return "" if value is None else str(value)
