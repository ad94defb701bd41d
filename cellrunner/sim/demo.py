"""A small demo cell for tests, benchmarks and trying the twin by hand.

A UR5e on a table (mount z = 0.9 m), a 0.15 m TCP along the flange Z, a two-finger io
gripper on DO0/DI0, and one 0.05 m, 0.3 kg cube on the table in front of the robot.
"""

from __future__ import annotations

import math

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix
from cellrunner.model.robots import robot_spec
from cellrunner.model.trajectory import Trajectory
from cellrunner.sim.description import (
    GripperDescription,
    PartDescription,
    TwinDescription,
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
# Closed-form IK and quintic joint blends, enough to drive the demo cell in tests and
# benchmarks; real jobs get their trajectories from cellrunner.planning.


def solve_ik(desc: TwinDescription, T_world_tcp: np.ndarray, q_seed_rad: np.ndarray) -> np.ndarray:
    """Joint angles (rad) putting the TCP at ``T_world_tcp``, on the branch the arm stays
    on when its TCP is led there from ``q_seed_rad`` in a straight line (closed-form IK
    tracked along it; raises ValueError when the line leaves the reachable space)."""
    from scipy.spatial.transform import Rotation, Slerp

    from cellrunner.planning.kinematics import ArmKinematics

    arm = ArmKinematics(desc.spec, desc.T_world_base, desc.T_flange_tcp)
    T_start = arm.T_world_tcp(np.asarray(q_seed_rad, dtype=float))
    q: np.ndarray | None = np.asarray(q_seed_rad, dtype=float)
    T_goal = np.asarray(T_world_tcp, dtype=float)
    turn = Slerp([0.0, 1.0], Rotation.from_matrix([T_start[:3, :3], T_goal[:3, :3]]))
    for s in np.linspace(0.0, 1.0, _IK_STEPS + 1)[1:]:
        T = np.eye(4)
        T[:3, :3] = turn(s).as_matrix()
        T[:3, 3] = (1 - s) * T_start[:3, 3] + s * T_goal[:3, 3]
        q = arm.ik_track(T, q) if q is not None else None
    if q is None:  # the line leaves the reachable space: the branch nearest the seed
        solutions = arm.ik_all(T_goal, np.asarray(q_seed_rad, dtype=float))
        if not solutions:
            raise ValueError("demo IK: the pose is out of reach")
        q = solutions[0]
    seed = np.asarray(q_seed_rad, dtype=float)
    return np.asarray(seed + (q - seed + np.pi) % (2 * np.pi) - np.pi)  # each joint within pi


#: poses along the line on which :func:`solve_ik` tracks its branch
_IK_STEPS = 20


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
