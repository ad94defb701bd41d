"""``cellrunner calibrate-camera CELL CAMERA --robot-host H [--views N] [--image-source S]
[--yes]``: the camera's pose from views of its calibration board (hand-eye), written into
``cameras.CAMERA.pose`` after showing the diff."""

from __future__ import annotations

import argparse

import numpy as np

from cellrunner.commissioning.arm import ArmReader
from cellrunner.commissioning.cellfile import pose_edit
from cellrunner.commissioning.session import Operator, offer
from cellrunner.errors import InfeasibleError, UsageError
from cellrunner.model.camera import FLANGE, WORLD
from cellrunner.model.expand import frame_pose
from cellrunner.model.geometry import invert, rpy_deg_of
from cellrunner.model.load import load_cell


def run(args: argparse.Namespace) -> int:
    cell = load_cell(args.cell)
    cameras = cell.cell.cameras
    if args.camera not in cameras:
        raise UsageError(
            f"unknown camera {args.camera!r}; known: {', '.join(cameras) or '(none: add cameras:)'}"
        )
    camera = cameras[args.camera]
    if camera.board is None:
        raise UsageError(f"camera {args.camera!r} has no board: add cameras.{args.camera}.board")
    from cellrunner.vision.handeye import MIN_VIEWS

    if not MIN_VIEWS <= args.views <= 40:
        raise UsageError(f"--views {args.views}: give {MIN_VIEWS} to 40")
    host = args.robot_host or cell.cell.robot.host
    if not host:
        raise UsageError("give --robot-host H (the cell file has no robot.host)")
    from cellrunner.commissioning.camera import take_shots, with_board
    from cellrunner.planning.world import CellWorld
    from cellrunner.vision.board import cv2, find_board
    from cellrunner.vision.handeye import check_fit, solve
    from cellrunner.vision.images import image_source
    from cellrunner.vision.views import plan_views

    cv2()  # OpenCV present, or say how to install it, before the arm moves
    operator = Operator()
    planning = with_board(cell, camera)
    world = CellWorld(planning)
    source = image_source(args.image_source, args.camera, camera, host)
    reader = ArmReader(cell, host)
    reader.connect()
    try:
        source.connect()
        views = plan_views(world, camera, args.views, reader.read_q_rad())
        if len(views) < MIN_VIEWS:
            raise InfeasibleError(
                f"only {len(views)} views of the board are reachable and collision-free "
                f"(at least {MIN_VIEWS}); move the board (or camera) where the arm reaches it "
                "from several sides"
            )
        operator.say(f"moving through {len(views)} views of the board (planned and checked)")
        shots = take_shots(planning, views, host, reader, source, operator.say)
    finally:
        source.close()
        reader.close()
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
    T = fit.T_mount_camera
    if camera.mount not in (FLANGE, WORLD):
        T = invert(frame_pose(cell.cell, camera.mount)) @ T
    xyz, rpy = T[:3, 3], rpy_deg_of(T[:3, :3])
    T_old = camera.pose.matrix()
    moved_mm = np.linalg.norm(T[:3, 3] - T_old[:3, 3]) * 1000
    R = T_old[:3, :3].T @ T[:3, :3]
    turned = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    board_xyz = ", ".join(f"{v:.4f}" for v in fit.T_mount_board[:3, 3])
    operator.say(
        f"camera {args.camera} in {camera.mount}: xyz [{', '.join(f'{v:.5f}' for v in xyz)}] m, "
        f"rpy [{', '.join(f'{v:.4f}' for v in rpy)}] deg ({moved_mm:.2f} mm and {turned:.3f} deg "
        f"from the pose in the file); board measured at xyz [{board_xyz}] m in "
        f"{'the world' if camera.eye_in_hand else 'the flange frame'}"
    )
    offer(
        pose_edit(cell.path, ("cameras", args.camera, "pose"), xyz, rpy),
        operator,
        args.yes,
        f"cameras.{args.camera}.pose",
    )
    return 0
