"""The task's ``on_error`` steps after a failure: safe outputs, a retreat, run best
effort (a step that cannot be planned from where the arm stands is skipped and the next
one runs; a step that fails is noted and the next one runs; a fault ends them), only
where the arm is able to move. The job ends with the failure that started them; how they went
is added to its message."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from cellrunner.errors import BackendError, CellrunnerError
from cellrunner.execution.job_records import AgendaItem
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step
from cellrunner.model.robot_state import Safety

#: failures after which the arm cannot move: on_error does not run
_ARM_STOPPED = (ResultCode.ESTOP, ResultCode.ROBOT_CONNECTION_LOST, ResultCode.PROTECTIVE_STOP)


@dataclass
class Cleanup:
    steps: list[Step]  # the task's on_error steps, expanded
    first: tuple[ResultCode, str] | None = None  # the failure they run after
    failures: list[str] = field(default_factory=list)
    #: steps whose plan failed from where the arm stood: skipped, the next one runs
    #: (best-effort recovery; check proved the rest brings the arm to its end)
    skipped: list[str] = field(default_factory=list)

    @property
    def running(self) -> bool:
        return self.first is not None

    def may_run(self, code: ResultCode, read_safety: Callable[[], Safety]) -> bool:
        """Whether on_error runs after a failure ``code``: there are steps and the arm is
        able to move (powered, linked, no stop)."""
        if not self.steps or code in _ARM_STOPPED:
            return False
        try:
            return read_safety() is Safety.NORMAL
        except (BackendError, CellrunnerError):
            return False

    def begin(self, code: ResultCode, message: str) -> list[AgendaItem]:
        """Start after the failure ``code``, ``message``: the agenda (stand still first,
        then each step)."""
        self.first = (code, message)
        return [AgendaItem(self.steps[0], behaviour="still", between=True)] + [
            AgendaItem(s) for s in self.steps
        ]

    def note(self, label: str, code: ResultCode, message: str, *, names_step: bool) -> bool:
        """An on_error step (``label``) failed with ``message`` (which starts with the
        step's label when ``names_step``: a timeout, a lost link, a refused plan); whether
        the next one may still run (nothing moved on a failed check or a refused plan)."""
        text = message if names_step else f"{label}: {message}"
        if code is ResultCode.PLANNING_FAILED:  # nothing moved: skipped, the next one runs
            self.skipped.append(text)
            return True
        self.failures.append(text)
        return not code.is_fault

    def result(self) -> tuple[ResultCode, str]:
        """The job's end: the first failure, with how on_error went."""
        assert self.first is not None  # cleanup ends only after it started
        first, why = self.first
        failures = self.failures
        note = "on_error done" if not failures else f"on_error failed: {'; '.join(failures)}"
        if self.skipped:
            note += f" (skipped: {'; '.join(self.skipped)})"
        return first, f"{why}; {note}" if why else note
