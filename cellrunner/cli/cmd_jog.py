"""``cellrunner jog CELL --robot-host H [--mode joint|base|tool]``: jog the arm from a
terminal (see :mod:`cellrunner.commissioning.jog` for keys, dead-man and thresholds)."""

from __future__ import annotations

import argparse
import sys

from cellrunner.errors import UsageError
from cellrunner.model.load import load_cell


def run(args: argparse.Namespace) -> int:
    cell = load_cell(args.cell)
    host = args.robot_host or cell.cell.robot.host
    if not host:
        raise UsageError("give --robot-host H (the cell file has no robot.host)")
    if not sys.stdin.isatty():
        raise UsageError("jog needs a terminal: keys are read as they are held")
    from cellrunner.commissioning.jog_terminal import JogSession
    from cellrunner.planning.world import CellWorld

    session = JogSession(CellWorld(cell), host, args.mode)
    session.connect()
    try:
        session.run()
    finally:
        session.close()
    return 0
