"""ur_rtde's control-script commands that answer a question or set a value (no motion).

Each is ``handler(program, controller)``: it reads its arguments from the program's input
registers and writes its answer to the output registers, as the control script's
``process_cmd`` branches do. The motion commands and the settings are
:class:`~cellrunner.twin.script.RtdeControlProgram` methods.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin.controller import Controller
from cellrunner.twin.kinematics import matrix_to_pose, pose_to_matrix


class Registers(Protocol):
    """The control script's registers, offset as its read_input_*_reg / write_output_*_reg do."""

    def in_int(self, ctl: Controller, i: int) -> int: ...
    def in_q(self, ctl: Controller, i: int) -> np.ndarray: ...
    def out_int(self, ctl: Controller, i: int, value: int) -> None: ...
    def out_double(self, ctl: Controller, i: int, value: float) -> None: ...
    def out_q(self, ctl: Controller, i: int, values: np.ndarray) -> None: ...


def within_joint_limits(ctl: Controller, q: np.ndarray) -> bool:
    lo, hi = np.radians(ctl.spec.joint_min_deg), np.radians(ctl.spec.joint_max_deg)
    return bool(np.all(q >= lo) and np.all(q <= hi))


def steptime(prog: Registers, ctl: Controller) -> None:
    prog.out_double(ctl, 0, ctl.period_s)


def joint_history(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, ctl.meas.q_rad)


def target_waypoint(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, ctl.target_tcp_pose)


def ik_args(prog: Registers, ctl: Controller) -> None:
    q = ctl.kinematics.inverse(pose_to_matrix(prog.in_q(ctl, 0)), prog.in_q(ctl, 6))
    if q is None:
        raise mo.MotionError("get_inverse_kin: no solution")
    prog.out_q(ctl, 0, q)


def ik_default(prog: Registers, ctl: Controller) -> None:
    q = ctl.kinematics.inverse(pose_to_matrix(prog.in_q(ctl, 0)), ctl.meas.q_rad)
    if q is None:
        raise mo.MotionError("get_inverse_kin: no solution")
    prog.out_q(ctl, 0, q)


def ik_has_solution(prog: Registers, ctl: Controller) -> None:
    seed = prog.in_q(ctl, 6) if prog.in_int(ctl, 0) == 61 else ctl.meas.q_rad
    q = ctl.kinematics.inverse(pose_to_matrix(prog.in_q(ctl, 0)), seed)
    prog.out_int(ctl, 1, int(q is not None))


def pose_within_limits(prog: Registers, ctl: Controller) -> None:
    q = ctl.kinematics.inverse(pose_to_matrix(prog.in_q(ctl, 0)), ctl.meas.q_rad)
    prog.out_int(ctl, 1, int(q is not None and within_joint_limits(ctl, q)))


def joints_within_limits(prog: Registers, ctl: Controller) -> None:
    prog.out_int(ctl, 1, int(within_joint_limits(ctl, prog.in_q(ctl, 0))))


def joint_torques(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, np.zeros(6))


def pose_trans(prog: Registers, ctl: Controller) -> None:
    T = pose_to_matrix(prog.in_q(ctl, 0)) @ pose_to_matrix(prog.in_q(ctl, 6))
    prog.out_q(ctl, 0, matrix_to_pose(T))


def tcp_offset(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, ctl.tcp_offset)


def tool_contact(prog: Registers, ctl: Controller) -> None:
    prog.out_int(ctl, 1, int(ctl.tool_contact()))


def fk_default(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, ctl.actual_tcp_pose)


def fk_args(prog: Registers, ctl: Controller) -> None:
    T = ctl.kinematics.flange(prog.in_q(ctl, 0)) @ pose_to_matrix(prog.in_q(ctl, 6))
    prog.out_q(ctl, 0, matrix_to_pose(T))


def is_steady(prog: Registers, ctl: Controller) -> None:
    prog.out_int(ctl, 1, int(ctl.is_steady()))


def flange_pose(prog: Registers, ctl: Controller) -> None:
    prog.out_q(ctl, 0, matrix_to_pose(ctl.kinematics.flange(ctl.meas.q_rad)))


def freedrive_status(prog: Registers, ctl: Controller) -> None:
    prog.out_int(ctl, 1, 0)


def read_contact(prog: Registers, ctl: Controller) -> None:
    prog.out_int(ctl, 1, int(ctl.meas.contact))
