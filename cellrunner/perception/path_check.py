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


def spot_ahead(
    known: KnownScene, q_rad: np.ndarray, index: int, half_m: float, margin_m: float
) -> np.ndarray | None:
    """Where a cube (half size ``half_m``, world-aligned) would stand in the way of the
    rest of a trajectory without touching the arm as it stands now at set-point ``index``
    (``margin_m`` apart): centred on where the TCP, else a wrist or the elbow, will pass,
    at the set-point two thirds along the rest first, then later ones, then earlier ones
    down to a third. Its world centre (m), None when every one meets the arm. What
    ``--inject intrusion@STEP`` drops in rehearsal."""
    q = np.asarray(q_rad, float)
    rest = len(q) - 1 - index
    if rest < 3:
        return None
    step = max(1, rest // 30)
    mark = index + rest * 2 // 3
    order = [*range(mark, len(q), step), *range(mark - step, index + rest // 3, -step)]
    robot = known.robot_at(q[index])
    grid = np.array([-1.0, 0.0, 1.0]) * half_m
    cube = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), axis=-1).reshape(-1, 3)
    tcp = known.world.kinematics.p_world_tcp_many(q[order])
    joints = known.world.collision.joint_frames(q[order])[:, 6:2:-1, :3, 3]  # wrists, elbow
    for where in (tcp[:, None, :], joints):
        for points in where:
            for p in points:
                if not near_any(robot, cube + p, margin_m + half_m / 2).any():
                    return np.asarray(p)
    return None
