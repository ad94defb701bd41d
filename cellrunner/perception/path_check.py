"""The rest of a trajectory checked against the map: does the arm, its tool or the part it
holds come within the padding of an occupied voxel anywhere along it?

A voxel is a cube; a point of it lies within ``pad`` of a solid when its centre lies
within ``pad`` + the cube's half diagonal. Between two configurations checked, no point of
the robot moves farther than ``sum_j |dq_j| * reach_j`` (each joint's lever arm bounded by
the robot's reach); configurations are checked every ``STEP_M`` of that bound, and the
distance grows by half of it, so nothing slips between two checks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cellrunner.perception.known import KnownScene
from cellrunner.perception.solids import near_any

#: configurations along a trajectory are checked this far apart (bound on any point's travel, m)
STEP_M = 0.02


@dataclass(frozen=True)
class Blocked:
    """The first configuration of a trajectory that comes too close to the map:
    its index (set-point), and the occupied voxel's world centre (m) it meets."""

    index: int
    voxel_m: tuple[float, float, float]
    voxels: int  # occupied voxels the robot meets there


def first_blocked(
    known: KnownScene,
    q_rad: np.ndarray,
    obstacles_m: np.ndarray,
    pad_m: float,
    *,
    held: object = None,
    reach_m: float | None = None,
) -> Blocked | None:
    """The first set-point of ``q_rad`` (N x 6) at which the robot (with ``held``, a part
    placed in the TCP frame) comes within ``pad_m`` of a voxel centre of ``obstacles_m``
    (M x 3, world; the caller adds the half diagonal); None when the way is clear."""
    q = np.asarray(q_rad, float)
    if not len(obstacles_m) or not len(q):
        return None
    reach = reach_m if reach_m is not None else known.world.spec.reach_m + 0.5
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q, axis=0)).sum(axis=1) * reach)])
    marks = np.floor(travel / STEP_M).astype(np.int64)
    checked = np.flatnonzero(np.concatenate([[True], marks[1:] != marks[:-1]]))
    if checked[-1] != len(q) - 1:
        checked = np.append(checked, len(q) - 1)
    frames = known.world.collision.joint_frames(q[checked])
    grow = pad_m + STEP_M / 2
    part = held if held is not None else None
    lo, hi = obstacles_m.min(axis=0), obstacles_m.max(axis=0)
    for k, i in enumerate(checked):
        solids = known.robot_at_frames(frames[k], part)  # type: ignore[arg-type]
        near = [
            (s, T)
            for s, T in solids
            if np.all(T[:3, 3] + s.radius_m + grow >= lo)
            and np.all(T[:3, 3] - s.radius_m - grow <= hi)
        ]
        if not near:
            continue
        hit = near_any(near, obstacles_m, grow)
        if hit.any():
            centre = obstacles_m[np.flatnonzero(hit)[0]]
            return Blocked(
                int(i), (float(centre[0]), float(centre[1]), float(centre[2])), int(hit.sum())
            )
    return None
