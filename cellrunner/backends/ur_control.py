"""ur_rtde's RTDEControlInterface in a process of its own.

Why: when the controller drops the connection, RTDEControlInterface reconnects by
itself, from its receive thread and from whichever thread is sending a command at the
time; the two reconnects race inside the library and corrupt its heap (``malloc():
mismatching next->prev_size``, SIGABRT or SIGSEGV) even when the program calls nothing.
No call order on our side avoids that, so the interface lives in a child process that
only this module talks to:

- one thread of the child (its main loop) touches the interface; the parent sends one
  request at a time over a pipe and waits for the answer with a bound;
- the library's own reconnect is never relied on: once the link is in doubt the parent
  kills the child (:meth:`ControlProcess.close`) and a reconnect builds a fresh one, so
  the object is always rebuilt from nothing;
- if the library crashes the child anyway, only the child dies: the parent sees the pipe
  close and reports :class:`ControlLost`.

The child imports nothing of cellrunner's but this module (spawned, so no state leaks
from the parent's threads).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from collections.abc import Generator
from typing import Any

from cellrunner.errors import InternalError

#: the RTDEControlInterface methods the parent may call (nothing else is forwarded)
METHODS = frozenset(
    {
        "servoJ",
        "servoStop",
        "stopJ",
        "stopScript",
        "isConnected",
        "isProgramRunning",
        "reuploadScript",
        "setTcp",
        "setPayload",
        "zeroFtSensor",
    }
)
#: a call that takes longer than this means the child or the link is stuck (s)
CALL_TIMEOUT_S = 5.0
#: :meth:`ControlProcess.start` looks at the pipe this often (s)
POLL_S = 0.01


class ControlLost(Exception):
    """The control process died, hung or refused to start; the link is to be rebuilt."""


def _serve(conn: Any, host: str, rate_hz: float) -> None:
    """The child: build the interface, then answer requests until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when we end
    quiet = os.open(os.devnull, os.O_WRONLY)  # ur_rtde prints to stdout/stderr: keep the
    os.dup2(quiet, 1)  # parent's (JSON) log clean; its errors reach the parent as exceptions
    os.dup2(quiet, 2)
    try:
        import rtde_control

        control = rtde_control.RTDEControlInterface(host, rate_hz)
    except Exception as exc:  # reported to the parent, which translates
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    conn.send(("ok", None))
    while True:
        try:
            name, args = conn.recv()
        except (EOFError, OSError):
            break  # the parent is gone
        if name == "quit":
            break
        try:
            conn.send(("ok", getattr(control, name)(*args)))
        except Exception as exc:  # ur_rtde raises RuntimeError with text
            conn.send(("error", str(exc)))
    os._exit(0)  # skip the library's destructor: its threads may be reconnecting


class ControlProcess:
    """The parent's handle on one child; construct (no I/O), :meth:`start`, calls,
    :meth:`close`. Not thread-safe: the backend's control thread is its only user."""

    def __init__(self, host: str, rate_hz: float, start_timeout_s: float) -> None:
        self.host = host
        self.rate_hz = rate_hz
        self.start_timeout_s = start_timeout_s
        self._process: Any = None
        self._conn: Any = None

    def start(self) -> None:
        """Spawn the child and build the interface (it uploads ur_rtde's control script);
        raises :class:`RuntimeError` with ur_rtde's text, or :class:`ControlLost` when
        the child does not answer within ``start_timeout_s``."""
        for _ in self.start_steps():
            time.sleep(POLL_S)

    def start_steps(self) -> Generator[None, None, None]:
        """:meth:`start` as bounded steps: spawn, then one look at the pipe per ``next``."""
        ctx = multiprocessing.get_context("spawn")
        parent, child = ctx.Pipe()
        self._process = ctx.Process(
            target=_serve, args=(child, self.host, self.rate_hz), daemon=True, name="ur-control"
        )
        self._process.start()
        child.close()
        self._conn = parent
        status, value = yield from self._answer_steps(self.start_timeout_s, "start")
        if status == "error":
            self.close()
            raise RuntimeError(value)

    @property
    def alive(self) -> bool:
        return self._process is not None and self._process.is_alive()

    def call(self, name: str, *args: Any, timeout_s: float = CALL_TIMEOUT_S) -> Any:
        """``RTDEControlInterface.<name>(*args)`` in the child; RuntimeError with the
        library's text, ControlLost when the child is gone or does not answer."""
        self._send(name, args)
        return self._value(self._answer(timeout_s, name))

    def call_steps(
        self, name: str, *args: Any, timeout_s: float = CALL_TIMEOUT_S
    ) -> Generator[None, None, Any]:
        """:meth:`call` as bounded steps: send, then one look at the pipe per ``next``."""
        self._send(name, args)
        return self._value((yield from self._answer_steps(timeout_s, name)))

    def _send(self, name: str, args: tuple[Any, ...]) -> None:
        if name not in METHODS:
            raise InternalError(
                f"unknown control call {name!r}; known: {', '.join(sorted(METHODS))}"
            )
        if self._conn is None:
            raise ControlLost("the control process is not running")
        try:
            self._conn.send((name, args))
        except (OSError, ValueError) as exc:
            self.close()
            raise ControlLost(f"the control process is gone: {exc}") from exc

    @staticmethod
    def _value(answer: tuple[str, Any]) -> Any:
        status, value = answer
        if status == "error":
            raise RuntimeError(value)
        return value

    def _answer(self, timeout_s: float, what: str) -> tuple[str, Any]:
        try:
            ready = self._conn.poll(timeout_s)
        except (EOFError, OSError):
            ready = True  # recv() reports it
        return self._received(ready, timeout_s, what)

    def _answer_steps(self, timeout_s: float, what: str) -> Generator[None, None, tuple[str, Any]]:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                ready = self._conn.poll(0)
            except (EOFError, OSError):
                ready = True  # recv() reports it
            if ready or time.monotonic() > deadline:
                return self._received(ready, timeout_s, what)
            yield

    def _received(self, ready: bool, timeout_s: float, what: str) -> tuple[str, Any]:
        """The answer waiting on the pipe; ControlLost (and the child ended) when there is
        none (``ready`` False: it did not come within ``timeout_s``) or the pipe broke."""
        try:
            if ready:
                status, value = self._conn.recv()
                return status, value
        except (EOFError, OSError):
            pass
        self.close()
        raise ControlLost(f"the control process did not answer {what} within {timeout_s:g} s")

    def close(self) -> None:
        """End the child (politely if it answers at once, else SIGKILL); idempotent."""
        process, conn = self._process, self._conn
        self._process = self._conn = None
        if conn is not None:
            with contextlib.suppress(OSError, ValueError):
                conn.send(("quit", ()))
        if process is not None:
            process.join(0.2)
            if process.is_alive():
                process.kill()
                process.join(2.0)
        if conn is not None:
            conn.close()
