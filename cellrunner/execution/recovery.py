"""Bringing the robot back for the PLC's Clear and Reset, on the control thread, one
bounded step per tick (the control loop never waits for the arm to power up), and
bringing it to a stand when the cell shuts down."""

from __future__ import annotations

import contextlib
from collections.abc import Generator

import numpy as np

from cellrunner.backends.base import RobotBackend
from cellrunner.errors import CellrunnerError
from cellrunner.model.robot_state import Safety

#: what a recovery ends with: the error that stopped it (None: it went through) and the
#: robot's safety state after it
Recovered = tuple[CellrunnerError | None, Safety]


def clear_steps(backend: RobotBackend, disconnected: bool) -> Generator[None, None, Recovered]:
    """Clearing, one step per ``next``: reconnect a lost link (``disconnected``), unlock a
    protective stop the job left behind (a job that ends in one, or is aborted while
    held), re-arm after an e-stop (power, brakes), each wait bounded by the backend. The
    controller refuses an unlock within 5 s of the stop: Clear fails then, and the next
    Clear tries again."""
    error = None
    try:
        if disconnected:
            backend.connect()
            yield
        if backend.read_state().safety is Safety.PROTECTIVE_STOP:
            backend.unlock_protective_stop()
            yield
        yield from backend.recover_from_estop_steps()
    except CellrunnerError as exc:  # e.g. the e-stop is still pressed
        error = exc
    return error, backend.read_state().safety


class Recovery:
    """Clearing's recovery under way (:func:`clear_steps`), one bounded step per tick."""

    def __init__(self) -> None:
        self._steps: Generator[None, None, Recovered] | None = None

    @property
    def active(self) -> bool:
        return self._steps is not None

    def start(self, backend: RobotBackend, disconnected: bool) -> None:
        if self._steps is None:
            self._steps = clear_steps(backend, disconnected)

    def step(self) -> Recovered | None:
        """One step; how the recovery ended once it did, else None."""
        assert self._steps is not None  # stepped only while active
        try:
            next(self._steps)
        except StopIteration as stop:
            self._steps = None
            recovered: Recovered = stop.value
            return recovered
        return None


def unlock_idle_stop(backend: RobotBackend) -> Recovered:
    """Reset with no job: unlock a latched protective stop. The controller refuses within
    5 s of the stop; the next Reset tries again."""
    error = None
    try:
        backend.unlock_protective_stop()
    except CellrunnerError as exc:
        error = exc
    return error, backend.read_state().safety


def stop_and_stand(backend: RobotBackend, max_ticks: int) -> None:
    """Stop the arm's motion (best effort) and wait, at most ``max_ticks`` periods, until
    it stands still (serve's shutdown)."""
    with contextlib.suppress(Exception):  # stopping is best effort; the job is closed after
        backend.stop_motion()
    for _ in range(max_ticks):
        state = backend.read_state()
        if float(np.max(np.abs(state.qd_rad_s))) < 1e-3:
            break
        backend.wait_period()
