"""Getting the robot link back while a job runs: bounded work polled once per tick, one
connection attempt per poll when its backoff delay (0.2 s doubling to 2 s) is due, for
at most the backend's ``reconnect_timeout_s`` (0: a single attempt). No poll blocks for longer than one attempt (the backend bounds it)."""

from __future__ import annotations

import enum
import time
from collections.abc import Callable

from cellrunner.backends.base import RobotBackend
from cellrunner.errors import CellrunnerError
from cellrunner.model.robot_state import Safety

#: reconnect attempts back off from this delay, doubling to 2 s (s)
RECONNECT_FIRST_DELAY_S = 0.2


class Link(enum.Enum):
    TRYING = "trying"  # poll again next tick
    BACK = "back"  # the link is up again
    LOST = "lost"  # given up: the job ends with 102 (:attr:`Reconnect.failure` says why)


class Reconnect:
    """One reconnect at a time: :meth:`begin`, then :meth:`poll` every tick."""

    def __init__(self) -> None:
        self.why: str | None = None  # a reconnect under way, and why it started
        self.failure = ""
        self._until = self._next = 0.0  # monotonic s
        self._delay = RECONNECT_FIRST_DELAY_S

    @property
    def active(self) -> bool:
        return self.why is not None

    def begin(self, why: str, backend: RobotBackend) -> None:
        now = time.monotonic()
        timeout_s = float(backend.reconnect_timeout_s)
        self.why, self._until = why, now + timeout_s
        self._next, self._delay = now, RECONNECT_FIRST_DELAY_S

    def poll(self, backend: RobotBackend, read_safety: Callable[[], Safety]) -> Link:
        """One attempt when it is due (``read_safety`` reads the robot's state, as the
        job reads it)."""
        if time.monotonic() < self._next:
            return Link.TRYING
        try:
            backend.reconnect(timeout_s=0.0)
            failure = (
                "the robot link is still down" if read_safety() is Safety.DISCONNECTED else None
            )
        except CellrunnerError as exc:
            failure = str(exc)
        why = self.why
        if failure is None:
            self.why = None
            return Link.BACK
        if time.monotonic() + self._delay >= self._until:
            self.why, self.failure = None, f"{why}; {failure}"
            return Link.LOST
        self._next = time.monotonic() + self._delay
        self._delay = min(2.0, self._delay * 2)
        return Link.TRYING
