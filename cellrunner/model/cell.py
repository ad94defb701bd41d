"""The cell file (SPEC section 3) as pydantic models. Pure data; references are
checked in :mod:`cellrunner.model.references`."""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

from pydantic import Field, field_validator, model_validator

from cellrunner.model.base import Name, PlacedShape, Pose, Shaped, Strict, Vec3
from cellrunner.model.camera import Camera
from cellrunner.model.conveyor import Conveyor
from cellrunner.model.marker import PrintedMarker
from cellrunner.model.robots import ROBOTS
from cellrunner.model.sim_inputs import SimBlock
from cellrunner.model.units import (
    Angle,
    AngularAccel,
    AngularSpeed,
    Force,
    Fraction,
    Mass,
    PositiveDuration,
    PositiveLength,
    Speed,
)
from cellrunner.model.watch import Watch

RobotModel = Literal[
    "ur3",
    "ur5",
    "ur10",
    "ur3e",
    "ur5e",
    "ur7e",
    "ur10e",
    "ur12e",
    "ur16e",
    "ur15",
    "ur18",
    "ur20",
    "ur30",
    "ur8long",
]
assert set(get_args(RobotModel)) == set(ROBOTS)

Joints = Annotated[list[Angle], Field(min_length=6, max_length=6)]


class Limits(Strict):
    """Motion limits plans may use, never above the controller's (checked per model)."""

    joint_speed: (
        AngularSpeed | Annotated[list[AngularSpeed], Field(min_length=6, max_length=6)] | None
    ) = None
    """Joint speed limit in deg/s, one value or six (never above the controller's). Example: `120`"""
    joint_accel: (
        AngularAccel | Annotated[list[AngularAccel], Field(min_length=6, max_length=6)] | None
    ) = None
    """Joint acceleration limit in deg/s^2, one value or six. Example: `300`"""
    tcp_speed: Speed | None = None
    """TCP speed cap in m/s. Example: `1.0`"""
    margin: Fraction = 0.95
    """Fraction of each limit that plans may use. Example: `0.95`"""


class Robot(Strict):
    model: RobotModel
    """Universal Robots arm model. Example: `ur5e`"""
    host: str | None = None
    """Controller address for the ur_rtde backend. Example: `192.168.1.101`"""
    backend: Literal["ur", "sim"] = "ur"
    """What run and serve drive: the arm through ur_rtde, or the MuJoCo twin. Example: `ur`"""
    mount: Pose = Field(default_factory=Pose)
    """The controller's base frame in the world (m, deg). Example: `{xyz: [0, 0, 0.9], rpy: [0, 0, 0]}`"""
    home: Joints
    """Home joint angles in degrees, base to wrist 3. Example: `[0, -90, 90, -90, -90, 0]`"""
    limits: Limits = Field(default_factory=Limits)
    """Motion limits plans may use. Example: `{joint_speed: 120, joint_accel: 300, tcp_speed: 1.0, margin: 0.95}`"""
    joint_range: (
        Annotated[
            list[Annotated[list[Angle], Field(min_length=2, max_length=2)]],
            Field(min_length=6, max_length=6),
        ]
        | None
    ) = None
    """Per-joint [min, max] in degrees, base to wrist 3, inside the arm's own ranges: narrows them (a cable that allows only +-180 deg on wrist 3, a safety joint limit); IK, planning, check and the twin keep to it. Example: `[[-180, 180], [-180, 0], [-160, 160], [-360, 360], [-360, 360], [-180, 180]]`"""
    tool: Name | None = None
    """With `tools:`, the tool mounted at start. Example: `jaws`"""


class Payload(Strict):
    mass: Mass = 0.0
    """Tool payload mass in kg. Example: `1.2`"""
    cog: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Centre of gravity in the flange frame, m. Example: `[0, 0, 0.05]`"""

    @property
    def cog_m(self) -> tuple[float, float, float]:
        """``cog`` as an (x, y, z) tuple in m."""
        x, y, z = self.cog
        return (x, y, z)


class OutputValue(Strict):
    output: Name
    """Output name from io.outputs. Example: `gripper_close`"""
    value: bool | float = True
    """Value written: true/false, or a number for an analog output. Example: `true`"""


class Cup(Strict):
    """A suction cup: its face centre in the TCP frame (m) and its radius (m)."""

    xyz: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Centre of the cup's face in the TCP frame, m. Example: `[0, 0, 0]`"""
    radius: PositiveLength = 0.02
    """Cup radius, m. Example: `0.02`"""


class BlowOff(Strict):
    output: Name
    """Output pulsed to blow the part off. Example: `blow_off`"""
    pulse: PositiveDuration = 0.1
    """Pulse length, s. Example: `0.1`"""


class Gripper(Strict):
    kind: Literal["io", "robotiq", "vacuum"] = "io"
    """io (a valve and a sensor), robotiq (2F-85/140 through its socket) or vacuum (suction cups). Example: `io`"""
    close: OutputValue | None = None
    """Output that closes the jaws. Example: `{output: gripper_close, value: true}`"""
    open: OutputValue | None = None
    """Output that opens the jaws (default: the close output, inverted). Example: `{output: gripper_open, value: true}`"""
    closed_sensor: Name | None = None
    """Input that confirms the jaws closed. Example: `gripper_closed`"""
    open_sensor: Name | None = None
    """Input that confirms the jaws opened. Example: `gripper_open`"""
    stroke: PositiveLength = 0.085
    """Jaw stroke in m (for the twin). Example: `0.085`"""
    close_time: PositiveDuration = 0.2  # s, jaws from fully open to closed (datasheet)
    """Jaws from fully open to closed, s (datasheet). Example: `0.2`"""
    host: str | None = None  # robotiq socket host (default: the robot host)
    """Robotiq socket host (default: the robot host). Example: `192.168.1.101`"""
    port: int = Field(default=63352, ge=1, le=65535)
    """Robotiq socket TCP port. Example: `63352`"""
    suction: OutputValue | None = None
    """Vacuum: the output that switches suction on. Example: `{output: vacuum_on, value: true}`"""
    vacuum_ok: Name | None = None
    """Vacuum: the input that confirms the cups hold vacuum. Example: `vacuum_ok`"""
    blow_off: BlowOff | None = None
    """Vacuum: an output pulsed on release to drop the part. Example: `{output: blow_off, pulse: 0.1}`"""
    cups: list[Cup] = Field(default_factory=list)
    """Vacuum: the cups, face centres in the TCP frame (m) and radii (m). Example: `[{xyz: [0, 0, 0], radius: 0.02}]`"""
    holding_force: Force | None = None
    """Vacuum: the pull in N the cups hold before the part tears off. Example: `150`"""


class Tool(Strict):
    tcp: Pose = Field(default_factory=Pose)
    """Flange (tool0) to tool centre point, m and deg. Example: `{xyz: [0, 0, 0.15]}`"""
    payload: Payload = Field(default_factory=Payload)
    """Tool payload. Example: `{mass: 1.2, cog: [0, 0, 0.05]}`"""
    gripper: Gripper | None = None
    """The gripper and its IO. Example: `{kind: io, close: {output: gripper_close, value: true}, closed_sensor: gripper_closed}`"""
    geometry: list[PlacedShape] = Field(default_factory=list)
    """Collision shapes of the tool in the flange frame. Example: `[{cylinder: {radius: 0.04, length: 0.15}, xyz: [0, 0, 0.075]}]`"""


class ToolChanger(Strict):
    """``lock`` output locks the mounted tool, ``locked`` input confirms it; ``rack`` gives
    each tool's rack frame (the TCP pose of that tool parked in the rack)."""

    lock: Name
    """Output that locks the mounted tool. Example: `changer_lock`"""
    locked: Name | None = None
    """Input that confirms the lock. Example: `changer_locked`"""
    rack: dict[Name, Name] = Field(default_factory=dict)
    """Each tool's rack frame (the TCP pose of that tool parked). Example: `{jaws: rack_jaws, cup: rack_cup}`"""
    approach: PositiveLength = 0.1
    """Distance in m along the rack frame's Z to approach from. Example: `0.1`"""


class Io(Strict):
    outputs: dict[Name, str] = Field(default_factory=dict)
    """Output names to controller channels: DOn standard, TOn tool, AOn analog. Example: `{gripper_close: DO0, beacon: DO3}`"""
    inputs: dict[Name, str] = Field(default_factory=dict)
    """Input names to controller channels: DIn standard, TIn tool, AIn analog. Example: `{gripper_closed: DI0, part_present: DI1}`"""


class Fixture(PlacedShape):
    name: Name
    """Fixture name, used in messages and reports. Example: `table`"""
    markers: list[PrintedMarker] = Field(default_factory=list)
    """ArUco markers printed on it (pose in the fixture's own frame, on its surface). Example: `[{dictionary: DICT_4X4_50, id: 3, size: 0.04, pose: {xyz: [0.2, 0, 0.025]}}]`"""


class Frame(Pose):
    parent: Name = "world"
    """Frame this pose is given in (world or another frame). Example: `world`"""


class Part(Shaped):
    name: Name
    """Part name. Example: `block`"""
    mass: Mass
    """Mass in kg. Example: `0.3`"""
    at: Name
    """Frame where the twin spawns it (where a TCP at that frame grips it). Example: `infeed`"""
    offset: Pose | None = None
    """Twin only: where the part really lies from `at` (what a camera would find). Example: `{xyz: [0.01, -0.02, 0], rpy: [0, 0, 15]}`"""
    friction: float = Field(default=0.8, gt=0, le=2)
    """Friction coefficient in the twin. Example: `0.8`"""
    markers: list[PrintedMarker] = Field(default_factory=list)
    """ArUco markers printed on it (pose in the part's own frame: its centre, upright as it lies at its frame; on its surface). Example: `[{dictionary: DICT_4X4_50, id: 7, size: 0.03, pose: {xyz: [0, 0, 0.025]}}]`"""


class Modbus(Strict):
    bind: str = "127.0.0.1"
    """Address the Modbus TCP server listens on. Example: `127.0.0.1`"""
    port: int = Field(default=502, ge=1, le=65535)
    """Modbus TCP port. Example: `502`"""
    heartbeat_timeout: PositiveDuration = 1.5
    """PLC heartbeat timeout in s: longer without a change sets PLC_WATCHDOG and holds. Example: `1.5`"""


SecurityPolicy = Literal[
    "none",
    "Basic256Sha256_Sign",
    "Basic256Sha256_SignAndEncrypt",
    "Aes128Sha256RsaOaep_Sign",
    "Aes128Sha256RsaOaep_SignAndEncrypt",
    "Aes256Sha256RsaPss_Sign",
    "Aes256Sha256RsaPss_SignAndEncrypt",
]


class OpcUa(Strict):
    endpoint: str = "opc.tcp://127.0.0.1:4840/cellrunner"
    """Endpoint URL the OPC UA server listens on. Example: `opc.tcp://127.0.0.1:4840/cellrunner`"""
    security: list[SecurityPolicy] = Field(
        default_factory=lambda: ["Basic256Sha256_SignAndEncrypt"],  # type: ignore[arg-type]  # mypy widens the literal in a lambda
        min_length=1,
    )
    """Security policies offered; none only when written here. Example: `[Basic256Sha256_SignAndEncrypt]`"""
    users: str | None = None
    """Users file (user -> salted hash), written by `cellrunner users add`. Example: `var/opcua-users.yaml`"""
    pki: str | None = None
    """PKI folder (own/, trusted/, rejected/); default pki/ beside the journal. Example: `pki`"""

    @field_validator("endpoint")
    @classmethod
    def _endpoint(cls, v: str) -> str:
        if not v.startswith("opc.tcp://"):
            from pydantic_core import PydanticCustomError

            raise PydanticCustomError("endpoint", f"endpoint {v!r} must start with opc.tcp://")
        return v


class Plc(Strict):
    modbus: Modbus | None = None
    """Modbus TCP server (SPEC section 7). Example: `{bind: 127.0.0.1, port: 502, heartbeat_timeout: 1.5}`"""
    opcua: OpcUa | None = None
    """OPC UA server (SPEC section 8). Example: `{endpoint: 'opc.tcp://127.0.0.1:4840/cellrunner', users: var/opcua-users.yaml}`"""


class PlaceTolerance(Strict):
    """How far a placed part may end from its target before the twin calls the place
    failed (SPEC section 11): ``distance`` m, ``angle`` deg."""

    distance: PositiveLength = 0.005
    """Largest distance from the target, m. Example: `0.005`"""
    angle: Annotated[Angle, Field(gt=0)] = 5.0
    """Largest turn from the target, deg. Example: `5`"""


class Cell(Strict):
    """A robot cell: robot, tool, IO, fixtures, frames, parts, tasks, PLC link, journal."""

    cell: Name
    """Cell name, used in logs, the journal and the PLC interface. Example: `line3-cell2`"""
    robot: Robot
    """The arm. Example: `{model: ur5e, home: [0, -90, 90, -90, -90, 0]}`"""
    tool: Tool = Field(default_factory=Tool)
    """The mounted tool. Example: `{tcp: {xyz: [0, 0, 0.15]}}`"""
    tools: dict[Name, Tool] = Field(default_factory=dict)
    """Several tools by name, with `robot.tool` the one mounted at start. Example: `{jaws: {tcp: {xyz: [0, 0, 0.15]}}}`"""
    tool_changer: ToolChanger | None = None
    """The tool changer: lock output, locked input, rack frames. Example: `{lock: changer_lock, locked: changer_locked, rack: {jaws: rack_jaws}}`"""
    io: Io = Field(default_factory=Io)
    """Names of the controller's inputs and outputs. Example: `{outputs: {gripper_close: DO0}, inputs: {gripper_closed: DI0}}`"""
    fixtures: list[Fixture] = Field(default_factory=list)
    """Static collision objects, poses in the world. Example: `[{name: table, box: {size: [1.2, 0.8, 0.04]}, pose: {xyz: [0.4, 0, 0.88]}}]`"""
    frames: dict[Name, Frame] = Field(default_factory=dict)
    """Named targets (m, deg). Example: `{infeed: {xyz: [0.45, -0.35, 0.93], rpy: [180, 0, 0]}}`"""
    parts: list[Part] = Field(default_factory=list)
    """What the twin spawns and a grip may carry. Example: `[{name: block, box: {size: [0.05, 0.05, 0.05]}, mass: 0.3, at: infeed}]`"""
    tasks: dict[Annotated[int, Field(ge=1, le=65535)], str] = Field(default_factory=dict)
    """PLC task numbers to task files. Example: `{1: tasks/pick_place.yaml}`"""
    plc: Plc = Field(default_factory=Plc)
    """The PLC link. Example: `{modbus: {bind: 127.0.0.1, port: 502}}`"""
    journal: str = "var/jobs.sqlite"
    """SQLite file, or a postgresql:// URL for a journal shared by many cells. Example: `var/jobs.sqlite`"""
    step_timeout: PositiveDuration = 60.0
    """A step that runs longer than this (s) fails with 105. Example: `60`"""
    place_tolerance: PlaceTolerance = Field(default_factory=PlaceTolerance)
    """How far a placed part may end from its target in the twin before the place fails (3). Example: `{distance: 0.005, angle: 5}`"""
    sim: SimBlock | None = None
    """Inputs the twin drives in rehearsal (dry-run and twin). Example: `{inputs: {part_present: {part_at: infeed}}}`"""
    cameras: dict[Name, Camera] = Field(default_factory=dict)
    """Cameras by name: intrinsics, image size, mount (world, a frame, flange) and pose, calibration board. Example: `{top: {intrinsics: {fx: 600, fy: 600, cx: 320, cy: 240}, image_size: [640, 480], pose: {xyz: [0.6, 0, 1.6], rpy: [180, 0, 90]}}}`"""

    conveyors: dict[Name, Conveyor] = Field(default_factory=dict)
    """Belts and round tables that carry parts past the arm (SPEC section 13): path, encoder, photo-eye, frame, window, top speed. Example: `{belt: {path: {line: {from: [0.9, -0.6, 0.8], to: [0.9, 0.8, 0.8]}}, encoder: {source: speed, mps: 0.25}, trigger: {input: part_at_eye}, eye_to_frame: 0.35, frame: belt_pick, window: [-0.1, 0.45], speed_max: 0.3}}`"""

    watch: Watch | None = None
    """A live obstacle map from depth cameras: jobs stop, wait or replan around what the cell file does not say. Example: `{cameras: [overhead], zone: {box: {size: [1.6, 1.2, 1.0]}, pose: {xyz: [0.4, 0, 1.4]}}, voxel: 0.02}`"""

    @model_validator(mode="before")
    @classmethod
    def _mounted_tool(cls, data: Any) -> Any:
        """With ``tools:``, ``tool`` is the one ``robot.tool`` names (names are checked,
        located, by the loader)."""
        if isinstance(data, dict) and isinstance(data.get("tools"), dict) and "tool" not in data:
            robot = data.get("robot")
            name = robot.get("tool") if isinstance(robot, dict) else None
            if isinstance(name, str) and name in data["tools"]:
                data = {**data, "tool": data["tools"][name]}
        return data
