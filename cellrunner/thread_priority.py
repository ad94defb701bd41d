"""A thread's own priority: real time for a control loop (and giving it back), a nice
value for the PLC servers and their workers.

Linux applies ``sched_setscheduler(0, ...)`` to the calling thread only, and every thread
and process it starts afterwards inherits the policy. A loop that raises its thread must
therefore run on a thread of its own, or give the priority back when it ends
(:func:`restore`): a caller's thread left at SCHED_FIFO makes every program it starts
later real-time too, where a busy one starves the rest of the machine."""

from __future__ import annotations

import contextlib
import os
import threading

#: a thread's scheduling policy and priority before :func:`realtime` raised it
Previous = tuple[int, int]


def realtime(priority: int) -> Previous | None:
    """Run the calling thread at SCHED_FIFO ``priority``. Returns what it ran at before
    (for :func:`restore`), None where the OS does not allow it (no CAP_SYS_NICE, not
    Linux), which leaves the thread as it was."""
    try:
        before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):
        return None
    return before


def restore(previous: Previous | None) -> None:
    """Give the calling thread back the policy :func:`realtime` returned (None: nothing)."""
    if previous is None:
        return
    policy, priority = previous
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(0, policy, os.sched_param(priority))


def nice(value: int) -> bool:
    """Run the calling thread (Linux: that thread alone; threads it starts afterwards
    inherit it) at nice ``value``; False where the OS does not allow it (raising needs
    CAP_SYS_NICE; not Linux), which leaves the thread as it was."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), value)
    except (AttributeError, OSError):
        return False
    return True
