"""PackML (ISA-TR88) cell states, their StateCurrent numbers, and the commands that
move between them (SPEC section 6).

Acting states (Starting, Completing, Holding, ...) end by themselves when their work is
done (``state_complete``); wait states (Idle, Held, Aborted, ...) change only on a
command (from the PLC) or an event (from the robot or the job: a protective stop, an
e-stop, the job's end). Every move is in one of the three tables below; anything else
raises :class:`TransitionRefused` naming the state and what is allowed from it.
"""

from __future__ import annotations

import enum

from cellrunner.errors import TransitionRefused as TransitionRefused  # re-exported
from cellrunner.model.codes import PackMLState as State


class Command(enum.Enum):
    START = "start"
    RESET = "reset"
    HOLD = "hold"
    UNHOLD = "unhold"
    SUSPEND = "suspend"
    UNSUSPEND = "unsuspend"
    STOP = "stop"
    ABORT = "abort"
    CLEAR = "clear"


class Event(enum.Enum):
    """What happens to the cell without a PLC command."""

    HOLD_STARTED = "hold_started"  # the job holds (protective stop, PLC watchdog, Hold)
    RESUMED = "resumed"  # a held job moves again
    JOB_ENDED = "job_ended"  # OK or NOK (not a fault): Completing
    JOB_ABORTED = "job_aborted"  # a fault ended the job: Aborting
    ESTOP = "estop"  # the e-stop was pressed
    LINK_LOST = "link_lost"  # the robot connection is gone with no job to end
    CLEAR_FAILED = "clear_failed"  # Clearing could not re-arm the robot (e-stop still pressed)


S, C, E = State, Command, Event

#: (state, command) -> next state
COMMANDS: dict[tuple[State, Command], State] = {
    (S.IDLE, C.START): S.STARTING,
    (S.COMPLETE, C.RESET): S.RESETTING,
    (S.STOPPED, C.RESET): S.RESETTING,
    (S.EXECUTE, C.HOLD): S.HOLDING,
    (S.HELD, C.UNHOLD): S.UNHOLDING,
    (S.EXECUTE, C.SUSPEND): S.SUSPENDING,
    (S.SUSPENDED, C.UNSUSPEND): S.UNSUSPENDING,
    (S.ABORTED, C.CLEAR): S.CLEARING,
}
_STOPPABLE = {
    S.IDLE,
    S.STARTING,
    S.EXECUTE,
    S.COMPLETING,
    S.COMPLETE,
    S.HOLDING,
    S.HELD,
    S.UNHOLDING,
    S.SUSPENDING,
    S.SUSPENDED,
    S.UNSUSPENDING,
    S.RESETTING,
}
for _s in _STOPPABLE:
    COMMANDS[(_s, C.STOP)] = S.STOPPING
for _s in _STOPPABLE | {S.STOPPING, S.STOPPED, S.CLEARING}:
    COMMANDS[(_s, C.ABORT)] = S.ABORTING

#: states a job is under way in (after Starting)
_RUNNING = {
    S.STARTING,
    S.EXECUTE,
    S.HOLDING,
    S.HELD,
    S.UNHOLDING,
    S.SUSPENDING,
    S.SUSPENDED,
    S.UNSUSPENDING,
}
#: states a fault may strike in (everything but Aborting/Aborted)
_ABORTABLE = set(State) - {S.ABORTING, S.ABORTED}

#: (state, event) -> next state
EVENTS: dict[tuple[State, Event], State] = {
    (S.EXECUTE, E.HOLD_STARTED): S.HOLDING,
    (S.HOLDING, E.RESUMED): S.UNHOLDING,
    (S.HELD, E.RESUMED): S.UNHOLDING,
    (S.CLEARING, E.CLEAR_FAILED): S.ABORTED,
}
for _s in _RUNNING:
    EVENTS[(_s, E.JOB_ENDED)] = S.COMPLETING
for _s in _ABORTABLE:
    EVENTS[(_s, E.JOB_ABORTED)] = S.ABORTING
    EVENTS[(_s, E.ESTOP)] = S.ABORTING
    EVENTS[(_s, E.LINK_LOST)] = S.ABORTING

#: acting state -> the state it ends in when its work is done
COMPLETES: dict[State, State] = {
    S.STARTING: S.EXECUTE,
    S.EXECUTE: S.COMPLETING,
    S.COMPLETING: S.COMPLETE,
    S.RESETTING: S.IDLE,
    S.HOLDING: S.HELD,
    S.UNHOLDING: S.EXECUTE,
    S.SUSPENDING: S.SUSPENDED,
    S.UNSUSPENDING: S.EXECUTE,
    S.STOPPING: S.STOPPED,
    S.ABORTING: S.ABORTED,
    S.CLEARING: S.STOPPED,
}


class StateMachine:
    """The current PackML state and its legal moves; knows nothing of robots."""

    def __init__(self, initial: State = S.STOPPED) -> None:
        self.state = initial

    def allowed(self) -> list[Command]:
        return [c for (s, c) in COMMANDS if s == self.state]

    def command(self, command: Command) -> State:
        nxt = COMMANDS.get((self.state, command))
        if nxt is None:
            allowed = ", ".join(c.value for c in self.allowed()) or "none"
            raise TransitionRefused(
                f"{command.value} is not allowed in state {self.state.display_name}; "
                f"allowed: {allowed}"
            )
        self.state = nxt
        return nxt

    def state_complete(self) -> State:
        nxt = COMPLETES.get(self.state)
        if nxt is None:
            raise TransitionRefused(
                f"state {self.state.display_name} is a wait state; it has no completion"
            )
        self.state = nxt
        return nxt

    def can(self, event: Event) -> bool:
        return (self.state, event) in EVENTS

    def on(self, event: Event) -> State:
        """Enter the state ``event`` leads to from the current one."""
        nxt = EVENTS.get((self.state, event))
        if nxt is None:
            allowed = ", ".join(e.value for (s, e) in EVENTS if s == self.state) or "none"
            raise TransitionRefused(
                f"event {event.value} cannot happen in state {self.state.display_name}; "
                f"possible: {allowed}"
            )
        self.state = nxt
        return nxt
