"""The PackML tables, transition by transition: every (state, command), (state, event)
and completion is either the table's move or refused with a message naming the state
and what is allowed."""

from __future__ import annotations

import itertools

import pytest

from cellrunner.execution.packml import (
    COMMANDS,
    COMPLETES,
    EVENTS,
    Command,
    Event,
    StateMachine,
    TransitionRefused,
)
from cellrunner.model.codes import PackMLState as S

#: SPEC section 6's moves, written out by hand (the table is checked against this, not itself)
EXPECTED_COMMANDS = {
    (S.IDLE, Command.START): S.STARTING,
    (S.COMPLETE, Command.RESET): S.RESETTING,
    (S.STOPPED, Command.RESET): S.RESETTING,
    (S.EXECUTE, Command.HOLD): S.HOLDING,
    (S.HELD, Command.UNHOLD): S.UNHOLDING,
    (S.EXECUTE, Command.SUSPEND): S.SUSPENDING,
    (S.SUSPENDED, Command.UNSUSPEND): S.UNSUSPENDING,
    (S.ABORTED, Command.CLEAR): S.CLEARING,
}
STOPPABLE = {
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
EXPECTED_COMMANDS |= {(s, Command.STOP): S.STOPPING for s in STOPPABLE}
EXPECTED_COMMANDS |= {
    (s, Command.ABORT): S.ABORTING for s in STOPPABLE | {S.STOPPING, S.STOPPED, S.CLEARING}
}

RUNNING = {
    S.STARTING,
    S.EXECUTE,
    S.HOLDING,
    S.HELD,
    S.UNHOLDING,
    S.SUSPENDING,
    S.SUSPENDED,
    S.UNSUSPENDING,
}
EXPECTED_EVENTS = {
    (S.EXECUTE, Event.HOLD_STARTED): S.HOLDING,
    (S.HOLDING, Event.RESUMED): S.UNHOLDING,
    (S.HELD, Event.RESUMED): S.UNHOLDING,
    (S.CLEARING, Event.CLEAR_FAILED): S.ABORTED,
}
EXPECTED_EVENTS |= {(s, Event.JOB_ENDED): S.COMPLETING for s in RUNNING}
for s in set(S) - {S.ABORTING, S.ABORTED}:
    for e in (Event.JOB_ABORTED, Event.ESTOP, Event.LINK_LOST):
        EXPECTED_EVENTS[(s, e)] = S.ABORTING

EXPECTED_COMPLETES = {
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


def test_the_tables_are_specs_section_6():
    assert COMMANDS == EXPECTED_COMMANDS
    assert EVENTS == EXPECTED_EVENTS
    assert COMPLETES == EXPECTED_COMPLETES


@pytest.mark.parametrize(("state", "command"), list(itertools.product(S, Command)))
def test_every_command_in_every_state(state, command):
    sm = StateMachine(state)
    expected = EXPECTED_COMMANDS.get((state, command))
    if expected is None:
        with pytest.raises(
            TransitionRefused, match=f"{command.value} is not allowed in state {state.display_name}"
        ):
            sm.command(command)
        assert sm.state is state  # a refused command changes nothing
    else:
        assert sm.command(command) is expected and sm.state is expected


@pytest.mark.parametrize(("state", "event"), list(itertools.product(S, Event)))
def test_every_event_in_every_state(state, event):
    sm = StateMachine(state)
    expected = EXPECTED_EVENTS.get((state, event))
    assert sm.can(event) is (expected is not None)
    if expected is None:
        with pytest.raises(
            TransitionRefused,
            match=f"event {event.value} cannot happen in state {state.display_name}",
        ):
            sm.on(event)
        assert sm.state is state
    else:
        assert sm.on(event) is expected


@pytest.mark.parametrize("state", list(S))
def test_every_completion(state):
    sm = StateMachine(state)
    expected = EXPECTED_COMPLETES.get(state)
    if expected is None:
        with pytest.raises(TransitionRefused, match=f"state {state.display_name} is a wait state"):
            sm.state_complete()
    else:
        assert sm.state_complete() is expected


def test_refusal_lists_what_is_allowed():
    with pytest.raises(TransitionRefused, match=r"allowed: stop, abort|allowed: abort, stop"):
        StateMachine(S.STARTING).command(Command.HOLD)


def test_a_job_cycle_with_a_protective_stop_and_an_estop():
    sm = StateMachine(S.STOPPED)
    path = [
        sm.command(Command.RESET),
        sm.state_complete(),
        sm.command(Command.START),
        sm.state_complete(),
        sm.on(Event.HOLD_STARTED),
        sm.state_complete(),
        sm.on(Event.RESUMED),
        sm.state_complete(),
        sm.on(Event.ESTOP),
        sm.state_complete(),
        sm.command(Command.CLEAR),
        sm.on(Event.CLEAR_FAILED),
        sm.command(Command.CLEAR),
        sm.state_complete(),
        sm.command(Command.RESET),
        sm.state_complete(),
    ]
    assert path == [
        S.RESETTING,
        S.IDLE,
        S.STARTING,
        S.EXECUTE,
        S.HOLDING,
        S.HELD,
        S.UNHOLDING,
        S.EXECUTE,
        S.ABORTING,
        S.ABORTED,
        S.CLEARING,
        S.ABORTED,
        S.CLEARING,
        S.STOPPED,
        S.RESETTING,
        S.IDLE,
    ]
