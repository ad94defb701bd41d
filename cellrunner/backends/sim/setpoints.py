"""What the sim backend's servoJ accepts, as the controller would: only sealed approved
trajectories sampled at its rate, and no set-point further from the last than the joint
speed limit allows (a real controller protective-stops on such a jump)."""

from __future__ import annotations

import numpy as np

from cellrunner.errors import BackendError
from cellrunner.model.trajectory import ApprovedTrajectory
from cellrunner.sim.description import TwinDescription, dh_forward

# servoJ set-points further apart than the joint speed limit allows (with this margin)
# are refused, as the controller would protective-stop on them.
SET_POINT_JUMP_MARGIN = 1.5


def accept(
    trajectory: ApprovedTrajectory, rate_hz: float, max_step_rad: np.ndarray
) -> tuple[ApprovedTrajectory, np.ndarray, np.ndarray]:
    """Check an approved trajectory once (seal, rate, speed): it, with its joint positions
    and speeds; raises BackendError for one the controller would refuse."""
    if not isinstance(trajectory, ApprovedTrajectory) or not trajectory.is_sealed:
        raise BackendError(
            "refusing an unsealed trajectory: only trajectories approved by check can move "
            "the robot"
        )
    traj = trajectory.trajectory
    if abs(traj.rate_hz - rate_hz) > 1e-9:
        raise BackendError(
            f"trajectory sampled at {traj.rate_hz:g} Hz, the controller runs at {rate_hz:g} Hz"
        )
    steps = np.abs(np.diff(traj.q_rad, axis=0))
    if len(steps) and (steps > max_step_rad).any():
        i, j = np.unravel_index(int(np.argmax(steps - max_step_rad)), steps.shape)
        raise BackendError(
            f"set-point {i + 1} of step {trajectory.step_index} ({trajectory.step_name}) "
            f"jumps {np.degrees(steps[i, j]):.2f} deg on joint {j + 1} in one period; the "
            f"joint speed limit allows {np.degrees(max_step_rad[j]):.2f} deg"
        )
    return trajectory, traj.q_rad, traj.qd_rad_s


def check_jump(
    trajectory: ApprovedTrajectory,
    index: int,
    q: np.ndarray,
    q_ref: np.ndarray,
    max_step_rad: np.ndarray,
) -> None:
    """Raise BackendError when set-point ``index`` (``q``) is further from the set-point
    now commanded (``q_ref``) than one period allows."""
    jump = np.abs(q - q_ref)
    if (jump > max_step_rad).any():
        j = int(np.argmax(jump - max_step_rad))
        raise BackendError(
            f"set-point {index} of step {trajectory.step_index} ({trajectory.step_name}) "
            f"jumps {np.degrees(jump[j]):.2f} deg on joint {j + 1} in one period; the "
            f"joint speed limit allows {np.degrees(max_step_rad[j]):.2f} deg"
        )


def step_limit_rad(joint_speed_max_deg_s: tuple[float, ...], rate_hz: float) -> np.ndarray:
    """The largest move (rad per joint) from one set-point to the next that servo takes."""
    return np.radians(joint_speed_max_deg_s) / rate_hz * SET_POINT_JUMP_MARGIN


def tracking_error_m(description: TwinDescription, q_ref: np.ndarray, q: np.ndarray) -> float:
    """Distance (m) between the TCP at set-point ``q_ref`` and the TCP at ``q``."""
    T_ft = description.T_flange_tcp
    p_ref = (dh_forward(description.spec, q_ref) @ T_ft)[:3, 3]
    p_act = (dh_forward(description.spec, q) @ T_ft)[:3, 3]
    return float(np.linalg.norm(p_ref - p_act))
