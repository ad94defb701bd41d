"""``cellrunner jog CELL --robot-host H [--input keyboard|gamepad|spacemouse|udp:PORT]
[--mode joint|base|tool] [--depth-source SPEC]``: the arm follows keys, a device or a program at the controller
rate (see :mod:`cellrunner.commissioning.servo` for the governor, dead band, smoothing and
timeout; :mod:`cellrunner.commissioning.inputs` for each input)."""

from __future__ import annotations

import argparse
import signal
import threading
from types import FrameType

from cellrunner.errors import UsageError
from cellrunner.model.load import load_cell


def run(args: argparse.Namespace) -> int:
    cell = load_cell(args.cell)
    host = args.robot_host or cell.cell.robot.host
    if not host:
        raise UsageError("give --robot-host H (the cell file has no robot.host)")
    from cellrunner.commissioning.inputs import open_input

    source = open_input(args.input, args.mode)
    from cellrunner.commissioning.jog_session import JogSession
    from cellrunner.planning.world import CellWorld

    stop = threading.Event()

    def on_term(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = signal.signal(signal.SIGTERM, on_term)
    world = CellWorld(cell)
    from cellrunner.execution.watch import watch_on_sources

    # a watched cell: its zone watch governs the jog (the twin's depth camera by default)
    watched = watch_on_sources(world, getattr(args, "depth_source", None), host)
    session = JogSession(world, host, source, watched=watched)
    try:
        session.connect()
        session.run(stop)
    finally:
        session.close()
        signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)
    return 0
