"""A command that runs until stopped ends within :data:`STOP_BOUND_S` of SIGTERM or Ctrl-C,
whatever its peer is doing.

Why a thread of its own: Python runs a signal's handler on the main thread, between two
bytecodes. A main thread blocked inside a native call never gets there: ur_rtde's
``speedStop`` on a link whose controller is gone waits in C++ (in the library's reconnect
loop, with the GIL released) for minutes, and the handler that would set the stop event
waits with it. The C-level handler still runs at once and writes the signal's number to
the wakeup fd (:func:`signal.set_wakeup_fd`); the watcher thread here reads that fd, sets
the stop event, and gives the main thread :data:`GRACE_S` to stop the arm, close the job
and return. If it has not, the watcher says so on stderr and ends the process with
:func:`os._exit` and the exit code the command gives on a clean stop. What was left
undone then is what a kill -9 leaves: the journal reconciles it on the next start, and a
controller whose link dropped has stopped its arm by itself. A second signal during the
grace ends the process at once.

Use::

    with stop_on_signals() as stop:
        loop.run(stop.event)
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import threading
import time
from collections.abc import Iterator
from types import FrameType

#: what a signal gives the main thread to finish cleanly before the process is ended (s)
GRACE_S = 1.5
#: the bound promised: the process is gone this long after SIGTERM or SIGINT (s)
STOP_BOUND_S = 2.0
#: the signals that stop a command
SIGNALS = (signal.SIGTERM, signal.SIGINT)
#: the byte the context's own exit writes to the wakeup pipe (no signal is numbered 0)
_CLOSING = 0
#: set by the first SIGTERM or SIGINT any command of this process was stopped by
_SIGNALLED = threading.Event()


def signalled() -> bool:
    """Whether a signal stopped a command of this process (its exit then skips the
    interpreter's teardown: :func:`end_process`)."""
    return _SIGNALLED.is_set()


class Stop:
    """The stop request of one command: :attr:`event` is set by the first SIGTERM or
    SIGINT; :attr:`signal_name` names it (``None`` until then)."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signal_name: str | None = None

    @property
    def reason(self) -> str:
        """``cellrunner stopped (SIGTERM)``: the words a job closed by the stop carries."""
        return f"cellrunner stopped ({self.signal_name or 'SIGTERM'})"

    def request(self, signum: int) -> None:
        if self.signal_name is None:
            self.signal_name = signal.Signals(signum).name
        _SIGNALLED.set()
        self.event.set()


@contextlib.contextmanager
def stop_on_signals(exit_code: int = 0, grace_s: float = GRACE_S) -> Iterator[Stop]:
    """SIGTERM and SIGINT set the yielded :class:`Stop`'s event; the process ends with
    ``exit_code`` if the block has not been left ``grace_s`` after the first of them.
    Call from the main thread; handlers and the wakeup fd are restored on leaving."""
    stop = Stop()
    finished = threading.Event()
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.request(signum)

    previous_handlers = {sig: signal.signal(sig, on_signal) for sig in SIGNALS}
    previous_fd = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    watcher = threading.Thread(
        target=_watch,
        args=(read_fd, stop, finished, exit_code, grace_s),
        name="cellrunner-stop",
        daemon=True,
    )
    watcher.start()
    try:
        yield stop
    finally:
        finished.set()
        signal.set_wakeup_fd(previous_fd)
        for sig, handler in previous_handlers.items():
            if stop.signal_name is not None:
                # The watcher may have set the stop before the main thread ran the signal's
                # Python handler; restored now, Python's own SIGINT handler would run for it
                # and raise KeyboardInterrupt in the process's last lines. A stopped
                # process is ending: its handler stays the stop's own, which only sets
                # the stop again.
                continue
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        with contextlib.suppress(OSError):
            os.write(write_fd, bytes([_CLOSING]))
        watcher.join(1.0)
        os.close(write_fd)
        os.close(read_fd)


def _watch(
    read_fd: int, stop: Stop, finished: threading.Event, exit_code: int, grace_s: float
) -> None:
    """The watcher thread: wait for a signal's byte, set the stop, bound the grace."""
    deadline_s: float | None = None
    while True:
        timeout_s = None if deadline_s is None else max(0.0, deadline_s - time.monotonic())
        ready, _, _ = select.select([read_fd], [], [], timeout_s)
        if finished.is_set():
            return
        if not ready:  # the grace is over and the main thread is still stuck
            _force_exit(stop, exit_code, f"did not stop within {grace_s:g} s")
        for signum in os.read(read_fd, 64):
            if signum == _CLOSING:
                return
            if signum not in SIGNALS:
                continue  # another signal some library handles (SIGCHLD, ...)
            if deadline_s is not None:  # a second signal: no more waiting
                _force_exit(stop, exit_code, "signalled twice")
            stop.request(signum)
            deadline_s = time.monotonic() + grace_s


def _force_exit(stop: Stop, exit_code: int, why: str) -> None:
    # os.write, not sys.stderr: the main thread may hold the stream's lock
    with contextlib.suppress(OSError):
        os.write(
            2,
            f"cellrunner: {why} after {stop.signal_name} (a peer that does not answer); "
            f"exiting {exit_code}\n".encode(),
        )
    os._exit(exit_code)


def end_process(exit_code: int, message: str | None = None) -> None:
    """End the process now with ``exit_code`` (``message`` a line on stderr first), past
    the destructors of native objects that would wait on a peer that is gone (ur_rtde's
    interfaces on a dropped link wait 0.5 s each for their reconnecting threads)."""
    import sys

    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
    if message is not None:
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.write(message + "\n")
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.flush()
    os._exit(exit_code)
