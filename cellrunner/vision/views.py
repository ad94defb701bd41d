"""Where the arm stands for each calibration view: the board in front of the camera at a
distance where it fills about half the image, tilted about different axes (hand-eye
needs turns about at least two) and rolled, each view reachable, inside the joint limits,
free of collisions with margin, and with the whole board inside the image.

A view is a pose of the board in the camera frame (``T_camera_board``); with the camera's
and the board's nominal mounts (the cell file's values) it gives the flange pose:
eye-in-hand ``T_world_flange = T_world_board inv(T_camera_board) inv(T_flange_camera)``,
eye-to-hand ``T_world_flange = T_world_camera T_camera_board inv(T_flange_board)``.
The nominal mounts may be centimetres off: views keep the board away from the image edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.camera import FLANGE, Camera
from cellrunner.model.expand import frame_pose
from cellrunner.model.geometry import invert
from cellrunner.vision.board import printed_size_m

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.planning.world import CellWorld

#: the board's printed width spans this fraction of the image width
FILL = 0.5
#: the board's corners stay this fraction of the image size away from its edges
EDGE_MARGIN = 0.06
#: views: (tilt deg, tilt axis azimuth deg, roll deg), most useful first
CANDIDATES = (
    [(0.0, 0.0, 0.0), (0.0, 0.0, 40.0)]
    + [(24.0, az, (-25.0, 0.0, 25.0)[k % 3]) for k, az in enumerate(range(0, 360, 60))]
    + [(34.0, az, (20.0, -20.0)[k % 2]) for k, az in enumerate(range(30, 390, 60))]
    + [(14.0, az, (-40.0, 40.0)[k % 2]) for k, az in enumerate(range(0, 360, 90))]
)


@dataclass(frozen=True)
class View:
    """A planned view: joint angles (rad) and the nominal flange and board-in-camera poses."""

    q_rad: np.ndarray
    T_world_flange: np.ndarray
    T_camera_board: np.ndarray
    label: str


def mounts(cell: Cell, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Nominal (camera, board) poses in their mounts: the flange one as is, the other in
    the world."""
    assert camera.board is not None

    def in_mount(mount: str, T: np.ndarray) -> np.ndarray:
        return T if mount == FLANGE else frame_pose(cell, mount) @ T

    return in_mount(camera.mount, camera.pose.matrix()), in_mount(
        camera.board.mount, camera.board.pose.matrix()
    )


def board_in_camera(
    camera: Camera, tilt_deg: float, azimuth_deg: float, roll_deg: float
) -> np.ndarray:
    """The board ``distance`` in front of the camera, facing it, tilted by ``tilt_deg``
    about an axis at ``azimuth_deg`` in the image plane, rolled by ``roll_deg``."""
    assert camera.board is not None  # calibration views need the camera's board
    width_m, _ = printed_size_m(camera.board)
    distance_m = camera.intrinsics.fx * width_m / (FILL * camera.image_size[0])
    facing = np.diag([1.0, -1.0, -1.0, 1.0])  # board Z towards the camera, X along image X
    axis = np.array([math.cos(math.radians(azimuth_deg)), math.sin(math.radians(azimuth_deg)), 0])
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = (
        Rotation.from_rotvec(math.radians(tilt_deg) * axis).as_matrix()
        @ Rotation.from_euler("z", roll_deg, degrees=True).as_matrix()
        @ facing[:3, :3]
    )
    T[:3, 3] = (0.0, 0.0, distance_m)
    return T


def in_image(camera: Camera, T_camera_board: np.ndarray) -> bool:
    """Every corner of the printed board projects inside the image, off its edges."""
    assert camera.board is not None  # calibration views need the camera's board
    w, h = (s / 2 for s in printed_size_m(camera.board))
    K = camera.intrinsics.matrix()
    W, H = camera.image_size
    for x, y in ((-w, -h), (w, -h), (w, h), (-w, h)):
        p = T_camera_board @ np.array([x, y, 0.0, 1.0])
        if p[2] <= 0:
            return False
        u, v = K[0, 0] * p[0] / p[2] + K[0, 2], K[1, 1] * p[1] / p[2] + K[1, 2]
        if not (EDGE_MARGIN * W < u < (1 - EDGE_MARGIN) * W):
            return False
        if not (EDGE_MARGIN * H < v < (1 - EDGE_MARGIN) * H):
            return False
    return True


def plan_views(world: CellWorld, camera: Camera, count: int, q_start_rad: np.ndarray) -> list[View]:
    """Up to ``count`` views, each reachable from the last by the nearest IK branch, in
    the joint limits, collision-free in ``world`` (which carries a flange-mounted board
    as tool geometry)."""
    kin = world.kinematics
    T_mount_camera, T_mount_board = mounts(world.loaded.cell, camera)
    views: list[View] = []
    q_near = np.asarray(q_start_rad, float)
    for tilt, azimuth, roll in CANDIDATES:
        if len(views) >= count:
            break
        T_cb = board_in_camera(camera, tilt, azimuth, roll)
        if not in_image(camera, T_cb):
            continue
        if camera.eye_in_hand:
            T_wf = T_mount_board @ invert(T_cb) @ invert(T_mount_camera)
        else:
            T_wf = T_mount_camera @ T_cb @ invert(T_mount_board)
        try:
            q = kin.ik_nearest(T_wf @ kin.T_flange_tcp, q_near)
        except InfeasibleError:
            continue
        if not world.collision.is_valid(q):
            continue
        views.append(View(q, T_wf, T_cb, f"tilt {tilt:g} deg at {azimuth:g} deg, roll {roll:g}"))
        q_near = q
    return views
