"""The cell's tasks as the PLC names them (by number or by name), and a job's params
checked against its task before the job is accepted (SPEC 8: 201 unknown task, 202 bad
params)."""

from __future__ import annotations

from typing import Any

from cellrunner.errors import InputError
from cellrunner.model.cellport import JobTicket
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import resolve_params
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue


class TaskMenu:
    """``tasks`` by their number; a name is looked up among them."""

    def __init__(self, tasks: dict[int, LoadedTask]) -> None:
        self.tasks = tasks

    def find(self, task: str | int) -> LoadedTask | None:
        if isinstance(task, int) or (isinstance(task, str) and task.isdigit()):
            return self.tasks.get(int(task))
        return next((t for t in self.tasks.values() if t.name == task), None)

    def param_names(self, task: str | int) -> list[str] | None:
        loaded = self.find(task)
        return list(loaded.task.params) if loaded else None

    def param_specs(self, task: str | int) -> list[tuple[str, str, str | None]] | None:
        """(name, type, unit) of the task's params in order, for the PLC's register layout."""
        loaded = self.find(task)
        return [(n, p.type, p.unit) for n, p in loaded.task.params.items()] if loaded else None

    def admit(
        self, task: str | int, params: dict[str, Any]
    ) -> tuple[LoadedTask, dict[str, ParamValue]] | JobTicket:
        """The task and its params resolved (defaults filled in, types checked), or the
        ticket that refuses the job."""
        loaded = self.find(task)
        if loaded is None:
            known = ", ".join(f"{n} ({t.name})" for n, t in self.tasks.items())
            return JobTicket(
                "", ResultCode.REJECT_UNKNOWN_TASK, f"unknown task {task!r}; known: {known}"
            )
        try:
            return loaded, resolve_params(loaded.task, params)
        except InputError as exc:
            return JobTicket("", ResultCode.REJECT_BAD_PARAMS, exc.diagnostics[0].message)
