"""The planning view of a cell: kinematics, collision model, limits, built once per cell."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.geometry import Placed
from cellrunner.model.gripper import open_pads
from cellrunner.model.load import LoadedCell
from cellrunner.model.robots import RobotSpec


@dataclass(frozen=True, eq=False)
class CellWorld:
    """Everything planning needs from a cell file, in SI and radians."""

    loaded: LoadedCell

    @property
    def spec(self) -> RobotSpec:
        return self.loaded.spec

    @cached_property
    def kinematics(self):
        from cellrunner.planning.kinematics import ArmKinematics
        c = self.loaded.cell
        return ArmKinematics(self.spec, c.robot.mount.matrix(), c.tool.tcp.matrix())

    @cached_property
    def tool(self) -> list[Placed]:
        """The declared tool geometry and, with a gripper, its finger pads fully open."""
        tool = self.loaded.cell.tool
        shapes = self.loaded.tool_shapes()
        if tool.gripper is not None:
            shapes += open_pads(tool.gripper.stroke, tool.tcp.matrix())
        return shapes

    @cached_property
    def fixtures(self) -> list[Placed]:
        return self.loaded.fixture_shapes()

    @cached_property
    def collision(self):
        from cellrunner.planning.collision import CollisionModel
        return CollisionModel(self.kinematics, self.tool, self.fixtures)

    @cached_property
    def limits(self):
        from cellrunner.planning.timing import MotionLimits
        lim = self.loaded.cell.robot.limits
        speed = tuple(lim.joint_speed) if isinstance(lim.joint_speed, list) else lim.joint_speed
        accel = tuple(lim.joint_accel) if isinstance(lim.joint_accel, list) else lim.joint_accel
        return MotionLimits.from_cell(self.spec, joint_speed_deg_s=speed, joint_accel_deg_s2=accel,
                                      tcp_speed_mps=lim.tcp_speed, margin=lim.margin)

    @cached_property
    def timing_memo(self) -> dict:
        """Timed, verified motion groups of this cell by their inputs (task_plan)."""
        return {}

    @property
    def q_home_rad(self) -> np.ndarray:
        return np.radians(self.loaded.cell.robot.home)

    def part_at(self, frame: str, T_world_tcp: np.ndarray) -> Placed | None:
        """The part spawned at ``frame``, placed in the TCP frame of a grip at ``T_world_tcp``."""
        from cellrunner.model.expand import frame_pose
        for part in self.loaded.cell.parts:
            if part.at == frame:
                T_world_part = frame_pose(self.loaded.cell, frame)
                T_tcp_part = geometry.invert(T_world_tcp) @ T_world_part
                return Placed(part.name, part.to_shape(self.loaded.resolve), T_tcp_part)
        return None
