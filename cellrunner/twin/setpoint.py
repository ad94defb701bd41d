"""The virtual controller's set-point, once a period: the running motion generator
advanced (with the brakes on, the set-point is where the arm is; a generator that fails
stops the program and the arm), and the target TCP pose and speeds that follow from it."""

from __future__ import annotations

from typing import Any

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin.kinematics import matrix_to_pose, matrix_to_rotvec, rotvec_to_matrix
from cellrunner.twin.modes import RobotMode


def advance_motion(ctl: Any, dt: float) -> None:
    """Advance the set-point of ``ctl`` (a :class:`~.controller.Controller`) by one
    period ``dt`` (s)."""
    previous_qd = ctl.target_qd
    previous_tcp = ctl.target_tcp_pose
    if ctl.robot_mode != RobotMode.RUNNING or ctl.estop_pressed:
        # brakes on: the set-point is where the arm is
        ctl.motion = None
        ctl.target_q, ctl.target_qd = ctl.meas.q_rad.copy(), np.zeros(6)
    elif ctl.motion is not None:
        try:
            q, qd, done = ctl.motion.advance(ctl.target_q, ctl.target_qd, dt)
        except mo.MotionError as exc:
            ctl.add_log(str(exc))
            ctl._halt_program(str(exc))
            q, qd, done = ctl.target_q, np.zeros(6), True
            ctl.motion = mo.Stop(ctl.accel_max)
        ctl.target_q, ctl.target_qd = np.asarray(q, float), np.asarray(qd, float)
        if done:
            ctl.motion = None
            ctl.target_qd = np.zeros(6)
    else:
        ctl.target_qd = np.zeros(6)
    ctl.target_qdd = (ctl.target_qd - previous_qd) / dt
    ctl.target_tcp_pose = matrix_to_pose(ctl.kinematics.tcp(ctl.target_q))
    ctl.target_tcp_speed = pose_rate(previous_tcp, ctl.target_tcp_pose, dt)


def pose_rate(p0: np.ndarray, p1: np.ndarray, dt: float) -> np.ndarray:
    """Finite-difference TCP twist (m/s, rad/s) between two UR poses."""
    w = matrix_to_rotvec(rotvec_to_matrix(p1[3:]) @ rotvec_to_matrix(p0[3:]).T)
    return np.concatenate([(p1[:3] - p0[:3]) / dt, w / dt])
