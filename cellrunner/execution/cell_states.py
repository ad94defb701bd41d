"""The cell's PackML state as the PLC's commands, the job and the robot move it, on the
control thread's clock: every state is shown for at least one period, Complete for
:data:`COMPLETE_DWELL_S` before the cell resets itself to Idle."""

from __future__ import annotations

from cellrunner.execution.job_records import JobPhase
from cellrunner.execution.packml import Command, Event, StateMachine
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.robot_state import Safety

#: Complete is shown this long before the cell resets itself to Idle
COMPLETE_DWELL_S = 0.1

#: acting states that complete on the next tick by themselves
_SELF_COMPLETING = frozenset({S.COMPLETING, S.ABORTING, S.STOPPING, S.CLEARING, S.RESETTING})
_HOLD_STATES = frozenset({S.HOLDING, S.HELD})


class CellStates:
    """A :class:`~cellrunner.execution.packml.StateMachine` with the time (``now_s``,
    robot s) and tick (``ticks``) at which its state was entered."""

    def __init__(self) -> None:
        self.sm = StateMachine(S.STOPPED)
        self.now_s = 0.0
        self.ticks = 0
        self._entered_s = 0.0
        self._entered_tick = 0

    @property
    def state(self) -> S:
        return self.sm.state

    def command(self, command: Command) -> None:
        """A PLC command (raises TransitionRefused when the state does not take it)."""
        self.sm.command(command)
        self.mark_entered()

    def on(self, event: Event) -> None:
        """``event`` when the state takes it."""
        if self.sm.can(event):
            self.sm.on(event)
            self.mark_entered()

    def mark_entered(self) -> None:
        self._entered_s, self._entered_tick = self.now_s, self.ticks

    def job_started(self) -> None:
        """Starting -> Execute."""
        self.sm.state_complete()
        self.mark_entered()

    def follow(self, phase: JobPhase) -> None:
        """One step towards the running job's ``phase`` (hold, held, resumed)."""
        state = self.sm.state
        if state is S.EXECUTE and phase in (JobPhase.HOLDING, JobPhase.HELD):
            self.sm.on(Event.HOLD_STARTED)
        elif state is S.HOLDING and phase is JobPhase.HELD:
            self.sm.state_complete()
        elif state in _HOLD_STATES and phase is JobPhase.EXECUTE:
            self.sm.on(Event.RESUMED)  # Unholding, shown for one period
        else:
            return
        self.mark_entered()

    def job_ended(self, fault: bool) -> None:
        """Completing, or Aborting for a ``fault`` (and for a job that ends OK in a state
        it cannot complete from)."""
        event = Event.JOB_ABORTED if fault else Event.JOB_ENDED
        if self.sm.can(event):
            self.sm.on(event)
        elif self.sm.can(Event.JOB_ABORTED):
            self.sm.on(Event.JOB_ABORTED)
        self.mark_entered()

    def settle(self, safety: Safety, has_job: bool, recovering: bool) -> None:
        """What the robot's ``safety`` and the passing of time do to the state: e-stop,
        link lost (with no job to end), acting states completing, Complete -> Idle.
        ``recovering``: Clearing's recovery is still re-arming the arm."""
        state = self.sm.state
        if self._entered_tick == self.ticks:
            return  # every state is visible for at least one period
        if state is S.EXECUTE and safety is Safety.NORMAL:
            return  # the common case while a job runs: nothing to do
        if safety is Safety.EMERGENCY_STOP and self.sm.can(Event.ESTOP):
            self.sm.on(Event.ESTOP)
        elif safety is Safety.DISCONNECTED and not has_job and self.sm.can(Event.LINK_LOST):
            self.sm.on(Event.LINK_LOST)
        elif state is S.CLEARING and recovering:
            return  # the arm is still being re-armed
        elif state in _SELF_COMPLETING or state is S.UNHOLDING:
            self.sm.state_complete()
        elif state is S.COMPLETE and self.now_s - self._entered_s >= COMPLETE_DWELL_S:
            self.sm.command(Command.RESET)
        else:
            return
        self.mark_entered()
