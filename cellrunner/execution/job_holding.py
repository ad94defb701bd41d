"""How a :class:`~cellrunner.execution.job.JobRunner` holds and resumes a job (PackML
Holding, Held): the PLC's requests (hold, unhold, abort), a protective stop's hold, and
the resume once :class:`~cellrunner.execution.hold.JobHold` allows it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.execution.hold import Held, JobHold
from cellrunner.execution.job_records import JobPhase
from cellrunner.model.codes import ResultCode
from cellrunner.model.hold_source import HoldSource

if TYPE_CHECKING:
    from cellrunner.execution.agenda import Agenda
    from cellrunner.execution.context import JobContext
    from cellrunner.execution.job_records import StepRows


class JobHolding:
    """The hold-handling half of the job runner (a mixin over its state)."""

    ctx: JobContext
    phase: JobPhase
    protective_stops: int
    _hold: JobHold
    _agenda: Agenda
    _rows: StepRows

    if TYPE_CHECKING:

        def _finish(self, code: ResultCode, message: str) -> None: ...
        def _log(self, event: str, **kw: Any) -> None: ...

    def _handle_request(self, what: str, source: HoldSource) -> None:
        if what == "abort":
            self._finish(ResultCode.ABORTED_BY_PLC, f"aborted during {self._agenda.label}")
        elif what == "hold" and self.phase is JobPhase.EXECUTE:
            self._enter_hold(source)
        elif what == "unhold" and self.phase is JobPhase.HELD:
            if self._hold.protective:
                # the controller is still stopped: unlock it (once its delay has passed),
                # then resume; resuming now would only meet the stop again
                self._hold.unhold_requested = True
            else:
                self._resume()

    def _enter_hold(self, source: HoldSource) -> None:
        self.phase = JobPhase.HOLDING
        self._hold.enter(source, self.ctx.now_s, self._agenda.step_index, self.ctx.last_state.q_rad)
        self._agenda.drop_motion()
        if source is not HoldSource.PROTECTIVE_STOP:
            self.ctx.backend.stop_motion()
        self._log("hold", reason=source.reason, source=source.value)
        current = self._agenda.current
        if current is not None:  # the journal: who held, in the step it held
            self._rows.held(current.step.index, current.attempt, f"{source.value}: {source.reason}")

    def _tick_held(self) -> None:
        if self.phase is JobPhase.HOLDING and np.max(np.abs(self.ctx.last_state.qd_rad_s)) < 1e-3:
            self.phase = JobPhase.HELD
        if not self._hold.protective:
            return  # a requested hold waits for unhold or abort
        held = self._hold.poll(
            self.ctx, self.protective_stops, self._agenda.step_index, self._agenda.label
        )
        if held is Held.FAILED:
            self._finish(ResultCode.PROTECTIVE_STOP, self._hold.failure)
        elif held is Held.RESUME:
            self._resume()

    def _resume(self) -> None:
        self._log("unhold")
        self.phase = JobPhase.EXECUTE
        self._agenda.restart()
