"""The planning view of a cell: kinematics, collision model, limits, built once per cell."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.geometry import Placed, Shape
from cellrunner.model.gripper import gripper_shapes, part_center_depth_m
from cellrunner.model.load import LoadedCell

if TYPE_CHECKING:
    from cellrunner.model.cell import Part
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.dynamics import ArmDynamics
    from cellrunner.planning.kinematics import ArmKinematics
    from cellrunner.planning.plan_store import PlanStore
    from cellrunner.planning.timing import MotionLimits
from cellrunner.model.robots import RobotSpec

#: worlds with placed parts kept per world (the states of the jobs planned last)
PLACED_WORLDS_MAX = 64


def placed_key(placed: tuple[Placed, ...]) -> tuple[object, ...]:
    """What tells two sets of placed parts apart: names and poses (to the nanometre)."""
    return tuple((p.name, np.round(p.T_parent_shape, 9).tobytes()) for p in placed)


@dataclass(frozen=True, eq=False)
class CellWorld:
    """Everything planning needs from a cell file, in SI and radians."""

    loaded: LoadedCell
    tool_key: tuple[str | None, str | None] | None = (
        None  # (tool, tcp_of) of a world made by with_tool; None: as the cell file mounts it
    )
    base: CellWorld | None = None  # the world with_tool made this one from
    #: obstacles beyond the cell file's fixtures (the watched zone's map, when a job
    #: replans around it; SPEC section 12)
    extra: tuple[Placed, ...] = ()
    #: the parts earlier steps of the job set down, where they were let go (fixtures
    #: ``placed:NAME@STEP``): obstacles to every later step, supports to a later place
    placed: tuple[Placed, ...] = ()
    #: the world without ``placed`` (None when ``placed`` is empty)
    unplaced: CellWorld | None = None
    #: the parts a job carried away from their frames and lost (a slip, a drop): no longer
    #: waiting there, and lying where check cannot know (:meth:`without_waiting`)
    gone: frozenset[str] = frozenset()

    @property
    def spec(self) -> RobotSpec:
        return self.loaded.spec

    @cached_property
    def kinematics(self) -> ArmKinematics:
        from cellrunner.planning.kinematics import ArmKinematics

        c = self.loaded.cell
        return ArmKinematics(self.spec, c.robot.mount.matrix(), c.tool.tcp.matrix())

    @cached_property
    def tool(self) -> list[Placed]:
        """The declared tool geometry and, with a gripper, its finger pads fully open."""
        tool = self.loaded.cell.tool
        shapes = self.loaded.tool_shapes()
        return shapes + gripper_shapes(tool.gripper, tool.tcp.matrix())

    def with_tool(self, name: str | None, tcp_of: str | None = None) -> CellWorld:
        """The same cell with tool ``name`` mounted (from ``tools:``); None: the bare
        flange, carrying tool ``tcp_of``'s TCP as a virtual point (no geometry, no payload).
        The parts the job set down stay where they lie."""
        if self.unplaced is not None:
            return self.unplaced.with_tool(name, tcp_of).with_placed(*self.placed)
        if self.base is not None:
            return self.base.with_tool(name, tcp_of)
        if name is not None and name == self.loaded.cell.robot.tool:
            return self
        key = (name, None if name is not None else tcp_of)
        worlds = self._tool_worlds
        if key not in worlds:
            from cellrunner.model.cell import Tool

            cell = self.loaded.cell
            if name is not None:
                tool = cell.tools[name]
            else:
                assert tcp_of is not None  # the bare flange carries some tool's TCP
                tool = Tool(tcp=cell.tools[tcp_of].tcp)
            loaded = dataclasses.replace(self.loaded, cell=cell.model_copy(update={"tool": tool}))
            worlds[key] = CellWorld(loaded, key, self)
        return worlds[key]

    @cached_property
    def _tool_worlds(self) -> dict[tuple[str | None, str | None], CellWorld]:
        return {}

    @cached_property
    def fixtures(self) -> list[Placed]:
        return self.loaded.fixture_shapes() + list(self.extra)

    def with_obstacles(self, *obstacles: Placed) -> CellWorld:
        """The same cell with ``obstacles`` beside its fixtures (a fresh collision model)."""
        return dataclasses.replace(self, extra=tuple(obstacles))

    def with_placed(self, *parts: Placed) -> CellWorld:
        """This world with ``parts`` (named ``placed:NAME@STEP``, placed in the world) set
        down besides the ones it has: one world per set of placed parts, kept by the world
        without them, so that a plan read back from the plan store finds the same ones.
        The arm's model, the tool and the limits are shared (a fresh collision model)."""
        if not parts:
            return self
        root = self.unplaced if self.unplaced is not None else self
        placed = (*self.placed, *parts)
        key = placed_key(placed)
        worlds = root._placed_worlds
        if key not in worlds:
            world = root._sharing(dataclasses.replace(root, placed=placed, unplaced=root))
            while len(worlds) >= PLACED_WORLDS_MAX:
                worlds.pop(next(iter(worlds)))  # the oldest
            worlds[key] = world
        return worlds[key]

    @cached_property
    def _placed_worlds(self) -> dict[tuple[object, ...], CellWorld]:
        return {}

    def _sharing(self, world: CellWorld) -> CellWorld:
        """``world``, a variant of this one, with this one's arm model, tool and limits
        where they are built: shared, not built again."""
        for name in ("kinematics", "tool", "limits"):
            if name in self.__dict__:
                world.__dict__[name] = self.__dict__[name]
        return world

    def at_its_frame(self, part: Part) -> tuple[Shape, np.ndarray]:
        """Part ``part``'s shape and its pose in the world waiting at its frame, as a grip
        at the frame holds it (jaws: its centre at the frame; cups: its top face)."""
        from cellrunner.model.expand import frame_pose

        shape = part.to_shape(self.loaded.resolve)
        depth = part_center_depth_m(self.loaded.cell.tool.gripper, shape)
        return shape, frame_pose(self.loaded.cell, part.at) @ geometry.pose_matrix((0, 0, depth))

    @cached_property
    def waiting_parts(self) -> list[Placed]:
        """The cell's parts where they wait to be picked, at their frames (as a grip at
        the frame holds them), named ``part:NAME``: obstacles until carried; then the
        parts the job set down (``placed:NAME@STEP``), which lie where they were let go. A part with
        an ``offset`` lies where a camera finds it, which check does not know (it proves
        the pick's pose box instead): it is no obstacle."""
        from cellrunner.model.body import WAITING_PREFIX

        out = [
            Placed(WAITING_PREFIX + part.name, *self.at_its_frame(part))
            for part in self.loaded.cell.parts
            if part.at in self.loaded.cell.frames and part.offset is None
        ]
        gone = {WAITING_PREFIX + name for name in self.gone}
        return [p for p in (*out, *self.placed) if p.name not in gone]

    def without_waiting(self, part_name: str) -> CellWorld:
        """This world once part ``part_name``, carried away from its frame, is lost: it
        waits there no more (on_error's states after a part slipped out in transit: its
        copy at the infeed is not where it fell, and a cleanup move home that passes by the
        infeed was refused for it, s100175). The arm's model, the tool and the limits are
        shared (a fresh collision model)."""
        from cellrunner.model.body import WAITING_PREFIX

        if part_name in self.gone or not any(
            p.name == WAITING_PREFIX + part_name for p in self.waiting_parts
        ):
            return self
        worlds = self._gone_worlds
        if part_name not in worlds:
            worlds[part_name] = self._sharing(
                dataclasses.replace(self, gone=self.gone | {part_name})
            )
        return worlds[part_name]

    @cached_property
    def _gone_worlds(self) -> dict[str, CellWorld]:
        return {}

    @cached_property
    def waiting_supports(self) -> dict[str, tuple[str, ...]]:
        """Per waiting part (``part:NAME``), the fixtures it rests on: those within the
        cell's place_tolerance of it (the jaws reaching around it may touch them)."""
        import coal

        from cellrunner.planning.coal_shapes import make_coal_shape

        def transform(T: np.ndarray) -> coal.Transform3s:
            return coal.Transform3s(np.asarray(T[:3, :3]), np.asarray(T[:3, 3]))

        reach_m = float(self.loaded.cell.place_tolerance.distance)
        out: dict[str, tuple[str, ...]] = {}
        for part in self.waiting_parts:
            shape, _ = make_coal_shape(part.shape)
            near = []
            for fixture in self.fixtures:
                other, _ = make_coal_shape(fixture.shape)
                d = coal.distance(
                    shape,
                    transform(part.T_parent_shape),
                    other,
                    transform(fixture.T_parent_shape),
                    coal.DistanceRequest(),
                    coal.DistanceResult(),
                )
                if d <= reach_m:
                    near.append(fixture.name)
            out[part.name] = tuple(near)
        return out

    @cached_property
    def collision(self) -> CollisionModel:
        from cellrunner.planning.collision import CollisionModel

        return CollisionModel(self.kinematics, self.tool, [*self.fixtures, *self.waiting_parts])

    @cached_property
    def limits(self) -> MotionLimits:
        from cellrunner.planning.timing import MotionLimits

        lim = self.loaded.cell.robot.limits
        speed = tuple(lim.joint_speed) if isinstance(lim.joint_speed, list) else lim.joint_speed
        accel = tuple(lim.joint_accel) if isinstance(lim.joint_accel, list) else lim.joint_accel
        return MotionLimits.from_cell(
            self.spec,
            joint_speed_deg_s=speed,
            joint_accel_deg_s2=accel,
            tcp_speed_mps=lim.tcp_speed,
            margin=lim.margin,
            dynamics=self.dynamics,
        )

    @cached_property
    def dynamics(self) -> ArmDynamics | None:
        """The arm's inverse dynamics with its tool and the heaviest part it may carry
        (None for an arm with no twin): motions are timed within its joints' torques."""
        from cellrunner.model.arm_dynamics import link_inertias
        from cellrunner.planning.dynamics import ArmDynamics

        if link_inertias(self.spec) is None:
            return None
        c = self.loaded.cell
        return ArmDynamics(
            self.spec,
            c.tool.tcp.matrix(),
            float(c.tool.payload.mass),
            c.tool.payload.cog_m,
            max((float(p.mass) for p in c.parts), default=0.0),
        )

    @cached_property
    def plans(self) -> PlanStore:
        """The approved plans of this cell by key (in memory, and under the project's
        ``var/plan-cache/``); one store for the cell whatever tool is mounted."""
        if self.unplaced is not None:
            return self.unplaced.plans
        if self.base is not None:
            return self.base.plans
        from cellrunner.planning.plan_store import PlanStore

        return PlanStore(self.loaded.root / "var" / "plan-cache")

    @cached_property
    def timing_memo(self) -> dict[Any, Any]:
        """Timed, verified motion groups of this cell by their inputs (task_plan)."""
        return {}

    @cached_property
    def motion_memo(self) -> dict[Any, Any]:
        """Planned motions of this cell (tool mounted) by their inputs (task_plan)."""
        return {}

    @cached_property
    def on_error_memo(self) -> dict[Any, Any]:
        """What on_error steps do from a state a job can fail in (planning.on_error)."""
        return {}

    @property
    def q_home_rad(self) -> np.ndarray:
        return np.radians(self.loaded.cell.robot.home)

    def part_at(
        self, frame: str, T_world_tcp: np.ndarray, T_world_slot: np.ndarray | None = None
    ) -> Placed | None:
        """The part spawned at ``frame``, placed in the TCP frame of a grip at
        ``T_world_tcp``; ``T_world_slot``: where it lies instead of the frame itself (the
        slot of a pattern the grip takes it from)."""
        from cellrunner.model.expand import frame_pose

        for part in self.loaded.cell.parts:
            if part.at == frame:
                shape = part.to_shape(self.loaded.resolve)
                depth = part_center_depth_m(self.loaded.cell.tool.gripper, shape)
                T_world_frame = (
                    frame_pose(self.loaded.cell, frame) if T_world_slot is None else T_world_slot
                )
                T_world_part = T_world_frame @ geometry.pose_matrix((0, 0, depth))
                T_tcp_part = geometry.invert(T_world_tcp) @ T_world_part
                return Placed(part.name, shape, T_tcp_part)
        return None

    def same_grip(self, part: Placed) -> Placed:
        """``part`` as gripped, or the part of an earlier grip of this world held within a
        nanometre of its pose: the grips of a pattern's slots, each reached by its own IK
        solution, then hold the part in one pose and share one collision model."""
        seen = self._grips.setdefault(part.name, [])
        for earlier in seen:
            if float(np.abs(earlier.T_parent_shape - part.T_parent_shape).max()) < 1e-9:
                return earlier
        if len(seen) < 64:
            seen.append(part)
        return part

    @cached_property
    def _grips(self) -> dict[str, list[Placed]]:
        return {}
