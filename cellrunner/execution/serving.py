"""A cell in production until it is told to stop: what ``cellrunner serve`` does between
reading the cell and exiting, callable without the CLI.

The links to the outside (the PLC servers, the status page) are the caller's: this
module knows no protocol and no web page, it only starts them through ``open_links`` and
closes them, last started first, after the running job was closed.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Callable
from typing import Any

from cellrunner.execution.assembly import AssembledCell

#: something started beside the cell, and how to stop it
Closer = Callable[[], None]


def serve(
    assembled: AssembledCell,
    stop: threading.Event,
    log: Any,  # a structlog logger (its ``exception`` too)
    *,
    stop_reason: Callable[[], str],
    open_links: Callable[[list[Closer]], None],
    on_serving: Callable[[], None],
    on_stopped: Callable[[], None] | None = None,
) -> None:
    """Connect, start the links (``open_links`` appends each one's closer as it starts
    it), run the control loop until ``stop`` is set, then close: the running job ended
    with ``stop_reason()`` (or the control loop's failure, which is raised again), the
    depth feed, ``on_stopped`` (a recording, the map), the results the journal holds
    reported, the links, the cell."""
    controller = assembled.controller
    controller.setup()
    closers: list[Closer] = []
    reason = ""
    try:
        open_links(closers)
        # everything built so far lives until exit: out of the collector's sight, so a full
        # collection (40-120 ms over the planning world and the OPC UA address space,
        # measured, holding the GIL) never stalls the Modbus heartbeat under a login flood
        gc.collect()
        gc.freeze()
        on_serving()
        if assembled.feed is not None:
            assembled.feed.start()
        assembled.loop.run(stop)
    except Exception as exc:  # a bug in the control loop: close the job saying so, then exit 1
        reason = f"cellrunner failed: {type(exc).__name__}: {exc}"
        log.exception("control_loop_failed", error=str(exc))
        raise
    finally:
        gc.unfreeze()  # collected as usual on the way out (native bindings check for leaks)
        reason = reason or stop_reason()
        controller.shutdown(reason)
        if assembled.feed is not None:
            assembled.feed.close()
        if on_stopped is not None:
            on_stopped()
        for what in controller.held_results():  # the journal tries once more as it closes
            log.warning("result_held_at_stop", held=what)
        for close in reversed(closers):
            close()
        controller.close()
        log.info("stopped", reason=reason)
