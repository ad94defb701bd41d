"""A small demo cell for tests, benchmarks and trying the twin by hand.

A UR5e on a table (mount z = 0.9 m), a 0.15 m TCP along the flange Z, a two-finger io
gripper on DO0/DI0, and one 0.05 m, 0.3 kg cube on the table in front of the robot.
"""

from __future__ import annotations

import math

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Placed, invert, pose_matrix
from cellrunner.model.robots import robot_spec
from cellrunner.model.trajectory import Trajectory
from cellrunner.sim.description import (
    GripperDescription,
    PartDescription,
    TwinDescription,
    dh_forward,
)

TABLE_TOP_Z_M = 0.90
CUBE_XYZ_M = (0.45, -0.35, 0.925)
CUBE_MASS_KG = 0.3
# Tool down (rpy 180, 0, 0) above the cube; the TCP is the grasp centre, gripped 5 mm
# above the cube's centre (the cube 5 mm along the TCP's Z, which points down)
CUBE_GRIP = pose_matrix((0.0, 0.0, 0.005), (180.0, 0.0, 0.0))
HOME_DEG = (0.0, -90.0, 90.0, -90.0, -90.0, 0.0)


def demo_description(**overrides: object) -> TwinDescription:
    """The demo cell; keyword ``overrides`` replace TwinDescription fields."""
    fields: dict[str, object] = dict(
        name="demo-cell",
        spec=robot_spec("ur5e"),
        T_world_base=pose_matrix((0.0, 0.0, 0.9)),
        T_flange_tcp=pose_matrix((0.0, 0.0, 0.15)),
        q_home_rad=tuple(math.radians(v) for v in HOME_DEG),
        tool_geometry=(Placed("body", Cylinder(0.04, 0.10), pose_matrix((0.0, 0.0, 0.05))),),
        payload_mass_kg=1.2,
        payload_cog_m=(0.0, 0.0, 0.06),
        gripper=GripperDescription(
            stroke_m=0.085, close_output="DO0", closed_sensor_input="DI0", open_sensor_input="DI1"
        ),
        fixtures=(Placed("table", Box((1.2, 0.8, 0.04)), pose_matrix((0.4, 0.0, 0.88))),),
        parts=(
            PartDescription(
                "cube",
                Box((0.05, 0.05, 0.05)),
                CUBE_MASS_KG,
                pose_matrix(CUBE_XYZ_M),
                T_grip_part=CUBE_GRIP,
            ),
        ),
        io_outputs=("DO0", "DO1", "DO2", "DO3"),
        io_inputs=("DI0", "DI1", "DI2"),
    )
    fields.update(overrides)
    # fields: keyword arguments of mixed types (the dataclass's own), not one value type
    return TwinDescription(**fields)  # type: ignore[arg-type]


# -- demo motion ----------------------------------------------------------------------------
# A tiny numerical IK and quintic joint blends, enough to drive the demo cell in tests and
# benchmarks; real jobs get their trajectories from cellrunner.planning.


def solve_ik(
    desc: TwinDescription, T_world_tcp: np.ndarray, q_seed_rad: np.ndarray, tol_m: float = 1e-6
) -> np.ndarray:
    """Joint angles (rad) putting the TCP at ``T_world_tcp``, near ``q_seed_rad``
    (damped least squares on the DH model; raises ValueError when it does not converge)."""
    T_base_flange = invert(desc.T_world_base) @ T_world_tcp @ invert(desc.T_flange_tcp)
    q = np.array(q_seed_rad, dtype=float)
    for _ in range(200):
        err = _pose_error(dh_forward(desc.spec, q), T_base_flange)
        if np.linalg.norm(err) < tol_m:
            return np.asarray(q_seed_rad + (q - q_seed_rad + np.pi) % (2 * np.pi) - np.pi)
        J = np.zeros((12, 6))
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = 1e-7
            J[:, j] = (_pose_error(dh_forward(desc.spec, q + dq), T_base_flange) - err) / 1e-7
        step = np.linalg.solve(J.T @ J + 1e-6 * np.eye(6), J.T @ err)
        q = q - step * min(1.0, 0.2 / max(float(np.abs(step).max()), 1e-12))
    raise ValueError("demo IK did not converge")


def _pose_error(T: np.ndarray, T_goal: np.ndarray) -> np.ndarray:
    # The full rotation-matrix difference, not its skew part (which is also zero at 180 deg).
    return np.concatenate([T[:3, 3] - T_goal[:3, 3], 0.3 * (T[:3, :3] - T_goal[:3, :3]).ravel()])


def quintic_blend(
    q0_rad: np.ndarray, q1_rad: np.ndarray, duration_s: float, rate_hz: float
) -> np.ndarray:
    """Samples (N x 6) of a rest-to-rest quintic from q0 to q1 at ``rate_hz``."""
    n = max(2, round(duration_s * rate_hz) + 1)
    s = np.linspace(0.0, 1.0, n)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return np.asarray(q0_rad) + np.outer(blend, np.asarray(q1_rad) - np.asarray(q0_rad))


def tcp_down_at(xyz_m: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """T_world_tcp with the tool pointing straight down (rpy 180, 0, 0) at ``xyz_m``."""
    return pose_matrix(tuple(xyz_m), (180.0, 0.0, 0.0))


def to_trajectory(samples_rad: np.ndarray, rate_hz: float) -> Trajectory:
    return Trajectory(rate_hz, np.arange(len(samples_rad)) / rate_hz, samples_rad)
