"""``cellrunner teach CELL FRAME --robot-host H [--points 3] [--yes]``: a frame from the
arm (the TCP pose where it stands, or origin, +X and XY-plane points), written into the
cell file after showing the diff."""

from __future__ import annotations

import argparse
import re

import numpy as np

from cellrunner.commissioning.arm import ArmReader
from cellrunner.commissioning.cellfile import pose_edit
from cellrunner.commissioning.session import Operator, offer
from cellrunner.commissioning.teach import frame_from_points, in_parent
from cellrunner.errors import UsageError
from cellrunner.model.expand import frame_pose
from cellrunner.model.load import load_cell

PROMPTS = (
    "jog the TCP to the frame's ORIGIN and press Enter",
    "jog the TCP to a point on the frame's +X axis and press Enter",
    "jog the TCP to a point in the frame's XY plane, on the +Y side, and press Enter",
)


#: frame names as the cell file takes them (model.base.Name)
FRAME_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")


def run(args: argparse.Namespace) -> int:
    if not FRAME_NAME.match(args.frame) or len(args.frame) > 64 or args.frame == "world":
        raise UsageError(
            f"frame name {args.frame!r}: use letters, digits, _ and - (not starting with a digit "
            "or -, at most 64, not 'world')"
        )
    cell = load_cell(args.cell)
    host = args.robot_host or cell.cell.robot.host
    if not host:
        raise UsageError("give --robot-host H (the cell file has no robot.host)")
    if args.points not in (1, 3):
        raise UsageError(
            f"--points {args.points}: give 1 (the TCP pose) or 3 (origin, +X, XY plane)"
        )
    from cellrunner.planning.world import CellWorld

    kinematics = CellWorld(cell).kinematics
    operator = Operator()
    reader = ArmReader(cell, host)
    reader.connect()
    try:
        if args.points == 1:
            operator.ask(
                f"jog the TCP to where frame {args.frame} belongs (its pose is the TCP's) and press Enter"
            )
            T_world_frame = kinematics.T_world_tcp(reader.read_q_rad())
        else:
            points = []
            for prompt in PROMPTS:
                operator.ask(prompt)
                points.append(kinematics.T_world_tcp(reader.read_q_rad())[:3, 3])
                operator.say(f"  read xyz [{', '.join(f'{v:.4f}' for v in points[-1])}] m in world")
            T_world_frame = frame_from_points(*points)
    finally:
        reader.close()
    xyz, rpy = in_parent(cell.cell, args.frame, T_world_frame)
    operator.say(
        f"frame {args.frame}: xyz [{', '.join(f'{v:.5f}' for v in xyz)}] m, "
        f"rpy [{', '.join(f'{v:.4f}' for v in rpy)}] deg"
    )
    if args.frame in cell.cell.frames:
        T_old = frame_pose(cell.cell, args.frame)
        moved_mm = np.linalg.norm(T_world_frame[:3, 3] - T_old[:3, 3]) * 1000
        R = T_old[:3, :3].T @ T_world_frame[:3, :3]
        turned = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
        operator.say(f"  {moved_mm:.2f} mm and {turned:.3f} deg from the pose in the file")
    offer(
        pose_edit(cell.path, ("frames", args.frame), xyz, rpy),
        operator,
        args.yes,
        f"frame {args.frame}",
    )
    return 0
