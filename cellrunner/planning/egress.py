"""Leaving a pick or a place the way the gripper went in.

A job normally starts where the last one ended (home). After an e-stop or an aborted job
the arm may stand with the gripper down at a pick or a place, the fingers around a part
that the planner does not model as an obstacle (only carried parts are). A joint move
from there swings the open fingers sideways through the part: on the demo it pushed the
block 54 mm off its infeed, and the next pick landed a pad on it (a protective stop).
So a job whose first motion is a planned move, and whose TCP starts in the corridor of
one of its own picks or places, or above a frame where a part of the cell rests (within
``CORRIDOR_RADIUS_M`` of the target's Z axis, between the target and its approach pose,
the tool pointing along it), first goes straight back along the tool's Z to the approach
height, as the descend came in, and is planned on from there. The retreat is part of
that move: timed and verified with it, and the step's row in ``check`` and the report
says why.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.expand import Step, frame_pose
from cellrunner.model.step import StepKind

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell

#: how far from the target's Z axis the TCP still counts as in the corridor (m)
CORRIDOR_RADIUS_M = 0.05
#: how far the tool may tilt from the target's Z and still count as in it (deg)
CORRIDOR_TILT_DEG = 30.0
#: how far past the target (pressed in) the TCP still counts as in it (m)
CORRIDOR_BEYOND_M = 0.02
#: a TCP within this of the approach pose is out already (m)
CORRIDOR_MIN_DEPTH_M = 0.002
#: the corridor's depth above a part's resting frame where no pick of the job says it (m)
RESTING_DEPTH_M = 0.10


@dataclass(frozen=True)
class Corridor:
    """Where a gripper goes down to a target: from ``depth_m`` back along its Z."""

    T_world_target: np.ndarray
    depth_m: float
    label: str


def corridors(steps: Sequence[Step], cell: Cell) -> list[Corridor]:
    """The corridors of the job's own picks and places (an approach, then a descend), and
    of the frames where the cell's parts rest (a job of another task, ``home`` say,
    may start in those after an e-stop)."""
    found = [
        Corridor(step.T_world_tcp, float(before.args.distance), step.label)
        for before, step in itertools.pairwise(steps)
        if step.kind is StepKind.DESCEND
        and before.kind is StepKind.APPROACH
        and step.T_world_tcp is not None
    ]
    found += [
        Corridor(frame_pose(cell, part.at), RESTING_DEPTH_M, f"{part.name}'s {part.at}")
        for part in cell.parts
    ]
    return found


def egress_pose(
    corridors: Sequence[Corridor], T_world_tcp: np.ndarray
) -> tuple[np.ndarray, str] | None:
    """Where a job starting with the TCP at ``T_world_tcp`` goes first, straight back along
    the tool's Z to the approach height, and why; None when it starts in none of
    ``corridors`` (the first that holds it counts)."""
    z_now = T_world_tcp[:3, 2]
    for c in corridors:
        T = c.T_world_target
        x, y, z = (geometry.invert(T) @ np.append(T_world_tcp[:3, 3], 1.0))[:3].tolist()
        inside = z + c.depth_m  # how far past the approach pose, towards the target
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(z_now @ T[:3, 2])))))
        if (
            math.hypot(x, y) <= CORRIDOR_RADIUS_M
            and CORRIDOR_MIN_DEPTH_M < inside <= c.depth_m + CORRIDOR_BEYOND_M
            and tilt <= CORRIDOR_TILT_DEG
        ):
            back = geometry.pose_matrix((0.0, 0.0, -inside))
            why = f"started {inside * 1000:.0f} mm inside {c.label}: leaves along the tool first"
            return np.asarray(T_world_tcp @ back), why
    return None
