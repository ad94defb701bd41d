"""``calibrate-camera``'s measurement: the arm moves through planned views of the camera's
board, the board is found in each picture, and the hand-eye fit gives the camera's pose in
its mount frame, ready to be written into ``cameras.CAMERA.pose``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.commissioning.arm import ArmReader
from cellrunner.commissioning.session import Operator
from cellrunner.errors import InfeasibleError
from cellrunner.model.camera import FLANGE, WORLD, Camera
from cellrunner.model.expand import frame_pose
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.geometry import invert, rpy_deg_of
from cellrunner.model.load import LoadedCell

if TYPE_CHECKING:
    from cellrunner.commissioning.camera import Shot
    from cellrunner.planning.world import CellWorld
    from cellrunner.vision.handeye import HandEye


@dataclass(frozen=True)
class CameraPose:
    """The measured pose of a camera in its mount frame: ``xyz_m`` (m) and ``rpy_deg``
    (deg), as the cell file writes them; ``moved_mm`` and ``turned_deg`` from the pose in
    the file; ``fit`` the hand-eye fit it came from."""

    xyz_m: np.ndarray
    rpy_deg: tuple[float, float, float]
    moved_mm: float
    turned_deg: float
    fit: HandEye


def measure_camera_pose(
    cell: LoadedCell,
    camera: Camera,
    view_count: int,
    host: str,
    image_source_spec: str | None,
    camera_name: str,
    operator: Operator,
) -> CameraPose:
    """Move the arm at ``host`` through ``view_count`` views of ``camera``'s board, find
    the board in each picture and fit the camera's pose; raises if too few views are
    reachable or the fit is poor (:func:`~cellrunner.vision.handeye.check_fit`)."""
    from cellrunner.commissioning.camera import with_board
    from cellrunner.planning.world import CellWorld
    from cellrunner.vision.board import cv2

    cv2()  # OpenCV present, or say how to install it, before the arm moves
    planning = with_board(cell, camera)
    world = CellWorld(planning)
    shots = _take_views(
        cell, planning, world, camera, view_count, host, image_source_spec, camera_name, operator
    )
    fit = _fit(world, camera, shots, operator)
    return _pose_in_mount(cell, camera, fit)


def _take_views(
    cell: LoadedCell,
    planning: LoadedCell,
    world: CellWorld,
    camera: Camera,
    view_count: int,
    host: str,
    image_source_spec: str | None,
    camera_name: str,
    operator: Operator,
) -> list[Shot]:
    """Plan reachable, collision-free views of the board in ``world`` and take a picture at
    each, moving the arm as a job of ``planning`` (the cell with the board) and reading its
    joints (rad) through ``cell``; the arm and the image source are closed again, whatever
    happens."""
    from cellrunner.commissioning.camera import take_shots
    from cellrunner.vision.handeye import MIN_VIEWS
    from cellrunner.vision.images import image_source
    from cellrunner.vision.views import plan_views

    source = image_source(image_source_spec, camera_name, camera, host)
    reader = ArmReader(cell, host)
    reader.connect()
    try:
        source.connect()
        views = plan_views(world, camera, view_count, reader.read_q_rad())
        if len(views) < MIN_VIEWS:
            raise InfeasibleError(
                Failure(
                    FailureKind.UNREACHABLE,
                    f"only {len(views)} views of the board are reachable and collision-free "
                    f"(at least {MIN_VIEWS})",
                    fix="move the board (or camera) where the arm reaches it from several sides",
                )
            )
        operator.say(f"moving through {len(views)} views of the board (planned and checked)")
        return take_shots(planning, views, host, reader, source, operator.say)
    finally:
        source.close()
        reader.close()


def _fit(world: CellWorld, camera: Camera, shots: list[Shot], operator: Operator) -> HandEye:
    """The hand-eye fit of the shots where the board was found (the others are left out and
    said), checked good enough."""
    from cellrunner.vision.board import find_board
    from cellrunner.vision.handeye import check_fit, solve

    assert camera.board is not None
    K = camera.intrinsics.matrix()
    distortion = np.asarray(camera.intrinsics.distortion, float)
    flanges, found = [], []
    for k, shot in enumerate(shots, 1):
        view = find_board(shot.image, camera.board, K, distortion)
        if view is None:
            operator.say(f"  view {k}: board not found; left out")
            continue
        flanges.append(world.kinematics.T_world_flange(shot.q_rad))
        found.append(view)
    fit = solve(camera.eye_in_hand, flanges, found, K, distortion)
    operator.say(
        f"hand-eye from {fit.views} views: reprojection {fit.rms_px:.3f} px rms; board poses "
        f"agree within {fit.spread_m * 1000:.3f} mm, {fit.spread_deg:.3f} deg rms; camera pose "
        f"1-sigma {fit.sigma_m * 1000:.3f} mm, {fit.sigma_deg:.4f} deg"
    )
    check_fit(fit)
    return fit


def _pose_in_mount(cell: LoadedCell, camera: Camera, fit: HandEye) -> CameraPose:
    """The fitted pose (flange or world frame) in the camera's mount frame, and how far it
    is from the pose in the file."""
    T = fit.T_mount_camera
    if camera.mount not in (FLANGE, WORLD):
        T = invert(frame_pose(cell.cell, camera.mount)) @ T
    T_old = camera.pose.matrix()
    moved_mm = float(np.linalg.norm(T[:3, 3] - T_old[:3, 3]) * 1000)
    R = T_old[:3, :3].T @ T[:3, :3]
    turned_deg = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
    return CameraPose(T[:3, 3], rpy_deg_of(T[:3, :3]), moved_mm, turned_deg, fit)
