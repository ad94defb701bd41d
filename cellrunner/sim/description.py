"""What the twin is built from: a neutral, frozen description of one cell (no MuJoCo).

The execution layer fills a :class:`TwinDescription` from the loaded cell file; the
twin never reads YAML itself. Frames follow :mod:`cellrunner.model.geometry`:
``T_parent_child`` 4x4 matrices, SI units.

Gripper convention: a parallel two-finger gripper at the TCP. The jaws move along the
TCP's X axis, symmetric about the TCP, and the pads span the TCP's Z around the TCP
(``pad_z_m`` below/above it), so the TCP is the centre of the grasp. Tool geometry
given by the cell should therefore end before the pads (it is physical in the twin).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Mesh, Placed, Shape, Sphere
from cellrunner.model.gripper import FINGER_SIZE_M, PAD_Z_M
from cellrunner.model.jaw_grip import JAW_GRIP_FORCE_N, JAW_PAD_FRICTION
from cellrunner.model.robots import RobotSpec

if TYPE_CHECKING:
    from cellrunner.planning.kinematics import ArmKinematics
    from cellrunner.sim.cameras import CameraDescription, MarkerDescription
    from cellrunner.sim.input_rules import InputRuleDescription


@dataclass(frozen=True)
class GripperDescription:
    """A valve-driven parallel gripper (SPEC ``tool.gripper`` with ``kind: io``).

    The jaws close while output ``close_output`` equals ``close_value`` and open
    otherwise, at ``jaw_speed_mps`` each, pushing with at most ``grip_force_N`` each.

    ``closed_sensor_input`` models the proximity switch of an io gripper: it reads true
    when the jaws are commanded closed, have come to rest (|speed| < 5 mm/s), and stopped
    between ``sensor_min_gap_m`` and ``stroke_m - sensor_min_gap_m`` of opening -- that
    is, they closed on something. Jaws that close on nothing travel to the end of their
    stroke (gap 0) and the switch stays false. ``open_sensor_input`` (optional) reads
    true when the gap is within ``sensor_min_gap_m`` of fully open.
    """

    stroke_m: float = 0.085  # full opening (gap between the pads, fully open)
    close_output: str = "DO0"
    close_value: bool | float = True
    closed_sensor_input: str | None = "DI0"
    open_sensor_input: str | None = None
    grip_force_N: float = JAW_GRIP_FORCE_N  # per jaw (model.jaw_grip: check's rule too)
    jaw_speed_mps: float = 0.15  # per jaw
    finger_size_m: tuple[float, float, float] = FINGER_SIZE_M  # thick, wide, long
    pad_z_m: tuple[float, float] = PAD_Z_M  # pad extent along TCP Z (planning checks the same)
    finger_mass_kg: float = 0.05
    friction: float = JAW_PAD_FRICTION
    sensor_min_gap_m: float = 0.002
    T_flange_tcp: np.ndarray | None = None  # the jaws' tool's TCP (default: the twin's)

    def __post_init__(self) -> None:
        if not self.stroke_m > 2 * self.sensor_min_gap_m:
            raise ValueError(f"gripper stroke {self.stroke_m} m is too small")


@dataclass(frozen=True)
class PartDescription:
    """A free body spawned at ``T_world_part`` (its shape centred on that frame).
    ``T_grip_part``: the part in the TCP of the grip a task means (a TCP at its frame:
    centred between the jaws, or its top face under the cups); a place is judged by it.
    Default: centred on the TCP, upright under a TCP pointing down."""

    name: str
    shape: Shape
    mass_kg: float
    T_world_part: np.ndarray
    friction: float = 0.8
    T_grip_part: np.ndarray = field(default_factory=lambda: np.diag([1.0, -1.0, -1.0, 1.0]))

    def __post_init__(self) -> None:
        if isinstance(self.shape, Mesh):
            raise ValueError(f"part {self.name!r}: mesh parts are not supported by the twin")
        if not self.mass_kg > 0:
            raise ValueError(f"part {self.name!r}: mass must be > 0 kg, got {self.mass_kg}")


@dataclass(frozen=True)
class PresenceSensor:
    """A light barrier: ``channel`` reads true while a part's centre is inside the box
    of half extents ``half_extents_m`` centred at ``center_world_m``."""

    channel: str
    center_world_m: tuple[float, float, float]
    half_extents_m: tuple[float, float, float]

    def sees(self, centre_m: np.ndarray) -> Any:
        """Whether a part centre (3,) is inside the box; per row for (n, 3)."""
        offset = np.abs(np.asarray(centre_m) - np.asarray(self.center_world_m))
        return np.all(offset <= np.asarray(self.half_extents_m), axis=-1)


@dataclass(frozen=True)
class TwinDescription:
    """Everything the MuJoCo twin needs to know about a cell.

    ``T_world_base``: the controller base frame (DH base) in the world.
    ``T_flange_tcp``: tool flange (DH frame 6) -> TCP. ``tool_geometry``: shapes in the
    flange frame. ``payload_mass_kg``/``payload_cog_m``: the tool's mass and centre of
    gravity in the flange frame (the gripper fingers' mass is included in it).
    ``fixtures`` and ``parts`` are in the world frame. IO channels are names such as
    ``DO0``/``DI0``/``TO1``/``AI0``.
    """

    spec: RobotSpec
    T_world_base: np.ndarray
    T_flange_tcp: np.ndarray
    q_home_rad: tuple[float, ...]
    tool_geometry: tuple[Placed, ...] = ()
    payload_mass_kg: float = 1.0
    payload_cog_m: tuple[float, float, float] = (0.0, 0.0, 0.05)
    gripper: GripperDescription | None = field(default_factory=GripperDescription)
    fixtures: tuple[Placed, ...] = ()
    parts: tuple[PartDescription, ...] = ()
    io_outputs: tuple[str, ...] = ("DO0",)
    io_inputs: tuple[str, ...] = ("DI0",)
    presence_sensors: tuple[PresenceSensor, ...] = ()
    vacuum: Any = None  # a VacuumDescription (sim.vacuum) for a suction gripper
    tool_changer: Any = None  # a ToolChangerDescription (sim.tool_changer) for several tools
    input_rules: tuple[InputRuleDescription, ...] = ()  # inputs the cell's sim: block drives
    cameras: tuple[CameraDescription, ...] = ()  # (sim.cameras): cameras and their boards
    markers: tuple[MarkerDescription, ...] = ()  # (sim.cameras): align markers on parts
    intruders: tuple[Any, ...] = ()  # IntruderDescription (sim.depth): only depth cameras see them
    depth: tuple[tuple[str, float, float, float], ...] = ()  # (camera, near m, far m, rate Hz)
    depth_noise_m: float = 0.0  # sim.depth_noise
    feed: Any = None  # a FeedDescription (sim.feed): parts fed before each job
    belts: tuple[Any, ...] = ()  # BeltDescription (sim.belts): conveyors that carry parts
    contact_force_limit_N: float = 60.0  # unexpected contact above this -> protective stop
    rigid_fixtures: frozenset[str] = frozenset()  # named in a step's contact: (sim.rigid_contacts)
    press_fits: tuple[tuple[str, float], ...] = ()  # (fixture, the fit's force N) (sim.press_fits)
    floor: bool = True
    name: str = "cell"

    def __post_init__(self) -> None:
        for attr in (
            "tool_geometry",
            "fixtures",
            "parts",
            "io_outputs",
            "io_inputs",
            "presence_sensors",
            "belts",
            "input_rules",
            "cameras",
            "markers",
            "intruders",
            "depth",
        ):
            object.__setattr__(self, attr, tuple(getattr(self, attr)))
        if len(self.q_home_rad) != 6:
            raise ValueError(f"q_home_rad needs 6 values, got {len(self.q_home_rad)}")
        for name in ("T_world_base", "T_flange_tcp"):
            if np.shape(getattr(self, name)) != (4, 4):
                raise ValueError(f"{name} must be a 4x4 matrix")
        names = [p.name for p in self.fixtures] + [p.name for p in self.parts]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"duplicate fixture/part names: {', '.join(dupes)}")
        if self.gripper is not None:
            g = self.gripper
            if g.close_output not in self.io_outputs:
                raise ValueError(
                    f"gripper close output {g.close_output!r} is not an output; "
                    f"known: {', '.join(self.io_outputs)}"
                )
            for ch in (g.closed_sensor_input, g.open_sensor_input):
                if ch is not None and ch not in self.io_inputs:
                    raise ValueError(
                        f"gripper sensor input {ch!r} is not an input; "
                        f"known: {', '.join(self.io_inputs)}"
                    )

    @property
    def rate_hz(self) -> float:
        return self.spec.rate_hz

    @property
    def press_fixtures(self) -> frozenset[str]:
        """The fixtures of the press fits (:mod:`.press_fits`)."""
        return frozenset(name for name, _ in self.press_fits)


def dh_forward(spec: RobotSpec, q_rad: np.ndarray) -> np.ndarray:
    """T_base_flange at ``q_rad`` (standard DH, theta_i = q_i), by the planner's
    pinocchio model of the arm (:class:`cellrunner.planning.kinematics.ArmKinematics`)."""
    return arm_kinematics(spec).T_world_flange(q_rad)


def arm_kinematics(spec: RobotSpec) -> ArmKinematics:
    """The kinematics of ``spec`` in its base frame with the flange as TCP, one per model
    and thread (a pinocchio model's data is not shared between threads)."""
    from cellrunner.planning.kinematics import ArmKinematics

    arms: dict[RobotSpec, ArmKinematics] = _ARMS.__dict__.setdefault("arms", {})
    arm = arms.get(spec)
    if arm is None:
        arm = arms[spec] = ArmKinematics(spec, np.eye(4), np.eye(4))
    return arm


_ARMS = threading.local()


def shape_volume_m3(shape: Shape) -> float:
    if isinstance(shape, Box):
        return float(np.prod(shape.size_m))
    if isinstance(shape, Cylinder):
        return math.pi * shape.radius_m**2 * shape.length_m
    if isinstance(shape, Sphere):
        return 4.0 / 3.0 * math.pi * shape.radius_m**3
    raise ValueError(f"no volume for {type(shape).__name__}")
