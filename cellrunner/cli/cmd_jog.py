"""``cellrunner jog CELL --robot-host H [--input keyboard|gamepad|spacemouse|udp:PORT]
[--mode joint|base|tool] [--depth-source SPEC]``: the arm follows keys, a device or a program at the controller
rate (see :mod:`cellrunner.commissioning.servo` for the governor, dead band, smoothing and
timeout; :mod:`cellrunner.commissioning.inputs` for each input)."""

from __future__ import annotations

import argparse

from cellrunner.cli.stopping import end_process, stop_on_signals
from cellrunner.errors import CellrunnerError, UsageError
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

    world = CellWorld(cell)
    from cellrunner.execution.watch import watch_on_sources

    # a watched cell: its zone watch governs the jog (the twin's depth camera by default)
    watched = watch_on_sources(world, getattr(args, "depth_source", None), host)
    session = JogSession(world, host, source, watched=watched)
    # SIGTERM and Ctrl-C end the session within 2 s, even while ur_rtde waits on a
    # controller that is gone (see cellrunner.cli.stopping)
    try:
        with stop_on_signals(exit_code=0) as stop:
            try:
                session.connect()
                session.run(stop.event)
            finally:
                session.close()
    except CellrunnerError as exc:
        if session.abandoned:  # the link dropped: say why, then past ur_rtde's destructors
            end_process(exc.exit_code, f"cellrunner jog: error: {exc}")
        raise
    if session.abandoned:
        end_process(0)
    return 0
