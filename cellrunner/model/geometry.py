"""Neutral geometry: shapes, poses and placed objects, shared by planning and the twin.

Poses are 4x4 homogeneous matrices named ``T_parent_child`` (a point in child
coordinates maps to parent coordinates by ``T_parent_child @ p``). ``rpy`` angles are
XYZ fixed-axis (roll about X, then pitch about fixed Y, then yaw about fixed Z), in
degrees, as SPEC section 3 and PolyScope's RPY display use them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cellrunner.model.rotation import rpy_rows


@dataclass(frozen=True)
class Box:
    size_m: tuple[float, float, float]  # full edge lengths x, y, z


@dataclass(frozen=True)
class Cylinder:
    radius_m: float
    length_m: float  # along the local Z axis, centred on the origin


@dataclass(frozen=True)
class Sphere:
    radius_m: float


@dataclass(frozen=True)
class Mesh:
    path: Path  # STL file, already resolved (see LoadedCell.resolve)
    scale: float = 1.0  # file units -> m


@dataclass(frozen=True, eq=False)
class Voxels:
    """Occupied voxels of the watched zone's map (SPEC section 12): cubes of edge
    ``voxel_m`` centred on ``centres_m`` (N x 3, world), to be kept ``padding_m`` from."""

    centres_m: np.ndarray
    voxel_m: float
    padding_m: float = 0.0

    def grown(self) -> np.ndarray:
        """The centres with every voxel within the padding of one added (N' x 3)."""
        reach = math.ceil(self.padding_m / self.voxel_m - 1e-9)
        if reach <= 0:
            return np.asarray(self.centres_m, float)
        r = np.arange(-reach, reach + 1)
        offsets = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
        offsets = offsets[np.einsum("ij,ij->i", offsets, offsets) <= reach * reach] * self.voxel_m
        points = (np.asarray(self.centres_m, float)[:, None, :] + offsets[None]).reshape(-1, 3)
        keys = np.round(points / (self.voxel_m / 2)).astype(np.int64)
        _, first = np.unique(keys, axis=0, return_index=True)
        return np.asarray(points[np.sort(first)])


Shape = Box | Cylinder | Sphere | Mesh | Voxels


@dataclass(frozen=True, eq=False)
class Placed:
    """A named shape at pose ``T_parent_shape`` (parent: world, or the tool flange)."""

    name: str
    shape: Shape
    T_parent_shape: np.ndarray


def rot_rpy_deg(rpy_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    """Rotation matrix of XYZ fixed-axis roll, pitch, yaw in degrees: Rz @ Ry @ Rx."""
    return np.array(rpy_rows(rpy_deg))


def pose_matrix(
    xyz_m: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
    rpy_deg: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """4x4 transform from a translation in m and XYZ fixed-axis angles in degrees."""
    T = np.eye(4)
    T[:3, :3] = rot_rpy_deg(rpy_deg)
    T[:3, 3] = xyz_m
    return T


def rpy_deg_of(R: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`rot_rpy_deg` (pitch in [-90, 90])."""
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    if abs(R[2, 0]) < 1 - 1e-9:
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = math.atan2(-R[0, 1], R[1, 1])
    return (math.degrees(roll), math.degrees(pitch), math.degrees(yaw))


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform."""
    Ti = np.eye(4)
    Ti[:3, :3] = T[:3, :3].T
    Ti[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return Ti


def tcp_pose_of(T: np.ndarray) -> tuple[float, ...]:
    """A UR pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad) of a transform."""
    from scipy.spatial.transform import Rotation

    return (
        *(float(v) for v in T[:3, 3]),
        *(float(v) for v in Rotation.from_matrix(T[:3, :3]).as_rotvec()),
    )
