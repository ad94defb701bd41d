"""PackML (ISA-TR88) cell states, their StateCurrent numbers, and the commands that
move between them (SPEC section 6).

Acting states (Starting, Completing, Holding, ...) end by themselves when their work is
done (``state_complete``); wait states (Idle, Held, Aborted, ...) change only on a
command or an event. Anything not allowed here raises :class:`TransitionRefused` naming
the state and what is allowed from it.
"""

from __future__ import annotations

import enum

from cellrunner.errors import CellrunnerError
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


class TransitionRefused(CellrunnerError):
    """A command that is not allowed in the current state."""


S, C = State, Command

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
_STOPPABLE = {S.IDLE, S.STARTING, S.EXECUTE, S.COMPLETING, S.COMPLETE, S.HOLDING, S.HELD,
              S.UNHOLDING, S.SUSPENDING, S.SUSPENDED, S.UNSUSPENDING, S.RESETTING}
for _s in _STOPPABLE:
    COMMANDS[(_s, C.STOP)] = S.STOPPING
for _s in _STOPPABLE | {S.STOPPING, S.STOPPED, S.CLEARING}:
    COMMANDS[(_s, C.ABORT)] = S.ABORTING

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

    def __init__(self, initial: State = S.STOPPED):
        self.state = initial

    def allowed(self) -> list[Command]:
        return [c for (s, c) in COMMANDS if s == self.state]

    def command(self, command: Command) -> State:
        nxt = COMMANDS.get((self.state, command))
        if nxt is None:
            allowed = ", ".join(c.value for c in self.allowed()) or "none"
            raise TransitionRefused(f"{command.value} is not allowed in state {self.state.display_name}; "
                                    f"allowed: {allowed}")
        self.state = nxt
        return nxt

    def state_complete(self) -> State:
        nxt = COMPLETES.get(self.state)
        if nxt is None:
            raise TransitionRefused(f"state {self.state.display_name} is a wait state; it has no completion")
        self.state = nxt
        return nxt

    def force(self, state: State) -> None:
        """Enter ``state`` on an event (a protective stop forces Holding, an e-stop Aborting)."""
        self.state = state
