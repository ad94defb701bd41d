"""``cellrunner calibrate-tcp CELL --robot-host H [--poses N] [--yes]``: the TCP from N >= 4
poses touching one fixed point, least squares with its residual, written into
``tool.tcp`` (xyz; its rpy is kept) after showing the diff."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from cellrunner.commissioning.arm import ArmReader
from cellrunner.commissioning.cellfile import pose_edit
from cellrunner.commissioning.session import Operator, offer
from cellrunner.commissioning.tcp import MIN_POSES, solve_tcp, too_alike
from cellrunner.errors import UsageError
from cellrunner.model.load import load_cell

if TYPE_CHECKING:
    import numpy as np

#: refused poses allowed in one session before giving up
MAX_REFUSED = 20


def run(args: argparse.Namespace) -> int:
    cell = load_cell(args.cell)
    host = args.robot_host or cell.cell.robot.host
    if not host:
        raise UsageError("give --robot-host H (the cell file has no robot.host)")
    if args.poses < MIN_POSES:
        raise UsageError(f"--poses {args.poses}: the TCP needs at least {MIN_POSES}")
    from cellrunner.planning.world import CellWorld

    kinematics = CellWorld(cell).kinematics
    operator = Operator()
    reader = ArmReader(cell, host)
    reader.connect()
    taken: list[np.ndarray] = []
    refused = 0
    try:
        while len(taken) < args.poses:
            operator.ask(
                f"pose {len(taken) + 1}/{args.poses}: touch the fixed point with the tool tip, the "
                "tool turned a new way, and press Enter"
            )
            T = kinematics.T_world_flange(reader.read_q_rad())
            why = too_alike(T, taken)
            if why is not None:
                refused += 1
                operator.say(f"  refused: {why}")
                if refused >= MAX_REFUSED:
                    operator.say(f"{refused} poses refused; giving up, the cell file is unchanged")
                    return 1
                continue
            taken.append(T)
    finally:
        reader.close()
    solution = solve_tcp(taken)
    tcp_mm = ", ".join(f"{v * 1000:.2f}" for v in solution.tcp_m)
    operator.say(
        f"TCP xyz [{tcp_mm}] mm in the flange frame; residual rms {solution.rms_m * 1000:.3f} mm, "
        f"max {solution.residuals_m.max() * 1000:.3f} mm (per pose: "
        f"{', '.join(f'{r * 1000:.3f}' for r in solution.residuals_m)} mm); "
        f"conditioning {solution.conditioning:.2f}"
    )
    offer(
        pose_edit(cell.path, ("tool", "tcp"), solution.tcp_m, None), operator, args.yes, "tool.tcp"
    )
    return 0
