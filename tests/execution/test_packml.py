"""The PackML state machine, transition by transition, against SPEC section 6 written the
way the SPEC says it: the paths a cell walks, and the rules that hold in many states at
once (stop, abort, faults, a job's end). Every (state, command), (state, event) and
completion the paths and rules name is taken; every other one is refused with a message
naming the state and what is allowed, and changes nothing."""

from __future__ import annotations

import itertools
from typing import Any

import pytest

from cellrunner.execution.packml import Command, Event, StateMachine, TransitionRefused
from cellrunner.model.codes import PackMLState as S

C, E = Command, Event
DONE = "done"  # the acting state finished its work (state_complete)

#: SPEC section 6 as walks: a start state, then (move, the state it leads to) in turn
PATHS: list[tuple[S, list[tuple[Any, S]]]] = [
    # a job: start, run, complete, reset to Idle
    (S.IDLE, [(C.START, S.STARTING), (DONE, S.EXECUTE), (DONE, S.COMPLETING)]),
    (S.COMPLETING, [(DONE, S.COMPLETE), (C.RESET, S.RESETTING), (DONE, S.IDLE)]),
    # hold by the PLC, and by the engine (a protective stop) resumed by it
    (S.EXECUTE, [(C.HOLD, S.HOLDING), (DONE, S.HELD), (C.UNHOLD, S.UNHOLDING), (DONE, S.EXECUTE)]),
    (S.EXECUTE, [(E.HOLD_STARTED, S.HOLDING), (E.RESUMED, S.UNHOLDING)]),
    (S.HELD, [(E.RESUMED, S.UNHOLDING)]),
    # suspend and unsuspend
    (S.EXECUTE, [(C.SUSPEND, S.SUSPENDING), (DONE, S.SUSPENDED), (C.UNSUSPEND, S.UNSUSPENDING)]),
    (S.UNSUSPENDING, [(DONE, S.EXECUTE)]),
    # stop, then reset
    (S.EXECUTE, [(C.STOP, S.STOPPING), (DONE, S.STOPPED), (C.RESET, S.RESETTING)]),
    # abort, clear (re-arming the robot), or a clear that finds the e-stop still pressed
    (S.EXECUTE, [(C.ABORT, S.ABORTING), (DONE, S.ABORTED), (C.CLEAR, S.CLEARING)]),
    (S.CLEARING, [(DONE, S.STOPPED)]),
    (S.CLEARING, [(E.CLEAR_FAILED, S.ABORTED)]),
]
#: the states a cell rests in until told otherwise (no completion of their own)
WAIT_STATES = {S.IDLE, S.HELD, S.SUSPENDED, S.COMPLETE, S.STOPPED, S.ABORTED}
#: Stop reaches every state but these; the Abort command and faults every state but Aborting/Aborted
NOT_STOPPABLE = {S.STOPPING, S.STOPPED, S.ABORTING, S.ABORTED, S.CLEARING}
NOT_ABORTABLE = {S.ABORTING, S.ABORTED}
FAULTS = (E.JOB_ABORTED, E.ESTOP, E.LINK_LOST)
#: a job is under way in these: its end (the runner's) leads to Completing
JOB_STATES = {
    S.STARTING,
    S.EXECUTE,
    S.HOLDING,
    S.HELD,
    S.UNHOLDING,
    S.SUSPENDING,
    S.SUSPENDED,
    S.UNSUSPENDING,
}


def _move(sm: StateMachine, move: Any) -> S:
    if move == DONE:
        return sm.state_complete()
    return sm.command(move) if isinstance(move, Command) else sm.on(move)


def _expected() -> dict[tuple[S, Any], S]:
    """Every legal move, from the paths and the rules."""
    moves = {}
    for start, steps in PATHS:
        state = start
        for move, nxt in steps:
            moves[(state, move)] = nxt
            state = nxt
    for state in S:
        if state not in NOT_STOPPABLE:
            moves[(state, C.STOP)] = S.STOPPING
        if state not in NOT_ABORTABLE:
            moves[(state, C.ABORT)] = S.ABORTING
            moves |= {(state, fault): S.ABORTING for fault in FAULTS}
        if state in JOB_STATES:
            moves[(state, E.JOB_ENDED)] = S.COMPLETING
    return moves


EXPECTED = _expected()


@pytest.mark.parametrize(("start", "steps"), PATHS)
def test_the_paths_of_spec_section_6(start: S, steps: list[tuple[Any, S]]) -> None:
    sm = StateMachine(start)
    assert [_move(sm, move) for move, _ in steps] == [nxt for _, nxt in steps]


@pytest.mark.parametrize(("state", "command"), list(itertools.product(S, Command)))
def test_every_command_in_every_state(state: S, command: Command) -> None:
    sm = StateMachine(state)
    expected = EXPECTED.get((state, command))
    if expected is None:
        with pytest.raises(
            TransitionRefused, match=f"{command.value} is not allowed in state {state.display_name}"
        ):
            sm.command(command)
        assert sm.state is state  # a refused command changes nothing
    else:
        assert sm.command(command) is expected and sm.state is expected


@pytest.mark.parametrize(("state", "event"), list(itertools.product(S, Event)))
def test_every_event_in_every_state(state: S, event: Event) -> None:
    sm = StateMachine(state)
    expected = EXPECTED.get((state, event))
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
def test_every_completion(state: S) -> None:
    sm = StateMachine(state)
    if state in WAIT_STATES:
        with pytest.raises(TransitionRefused, match=f"state {state.display_name} is a wait state"):
            sm.state_complete()
        assert sm.state is state
    else:
        expected = EXPECTED.get((state, DONE))
        assert expected is not None, f"{state.display_name} acts but no path finishes it"
        assert sm.state_complete() is expected


def test_every_state_is_reachable_from_idle_and_idle_from_every_state() -> None:
    def reach(start: S) -> set[S]:
        seen, todo = {start}, [start]
        while todo:
            state = todo.pop()
            for (src, _), dst in EXPECTED.items():
                if src is state and dst not in seen:
                    seen.add(dst)
                    todo.append(dst)
        return seen

    assert reach(S.IDLE) == set(S)
    assert all(S.IDLE in reach(state) for state in S)


def test_refusal_lists_what_is_allowed() -> None:
    with pytest.raises(TransitionRefused, match=r"allowed: stop, abort|allowed: abort, stop"):
        StateMachine(S.STARTING).command(Command.HOLD)
