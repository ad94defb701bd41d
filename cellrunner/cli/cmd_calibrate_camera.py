"""``cellrunner calibrate-camera CELL CAMERA --robot-host H [--views N] [--image-source S]
[--yes]``: the camera's pose from views of its calibration board (hand-eye), written into
``cameras.CAMERA.pose`` after showing the diff."""

from __future__ import annotations

import argparse

from cellrunner.commissioning.cellfile import pose_edit
from cellrunner.commissioning.session import Operator, offer
from cellrunner.errors import UsageError
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
    from cellrunner.commissioning.camera_pose import measure_camera_pose

    operator = Operator()
    pose = measure_camera_pose(
        cell, camera, args.views, host, args.image_source, args.camera, operator
    )
    board_xyz = ", ".join(f"{v:.4f}" for v in pose.fit.T_mount_board[:3, 3])
    operator.say(
        f"camera {args.camera} in {camera.mount}: "
        f"xyz [{', '.join(f'{v:.5f}' for v in pose.xyz_m)}] m, "
        f"rpy [{', '.join(f'{v:.4f}' for v in pose.rpy_deg)}] deg ({pose.moved_mm:.2f} mm and "
        f"{pose.turned_deg:.3f} deg from the pose in the file); board measured at "
        f"xyz [{board_xyz}] m in {'the world' if camera.eye_in_hand else 'the flange frame'}"
    )
    offer(
        pose_edit(cell.path, ("cameras", args.camera, "pose"), pose.xyz_m, pose.rpy_deg),
        operator,
        args.yes,
        f"cameras.{args.camera}.pose",
    )
    return 0
