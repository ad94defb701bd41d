"""The cell file (SPEC section 3) as pydantic models. Pure data; references are
checked in :mod:`cellrunner.model.references`."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from cellrunner.model.base import Name, PlacedShape, Pose, Shaped, Strict, Vec3
from cellrunner.model.robots import ROBOTS
from cellrunner.model.units import (
    Angle, AngularAccel, AngularSpeed, Duration, Force, Fraction, Mass, PositiveDuration,
    PositiveLength, Speed,
)

RobotModel = Literal["ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e"]
assert set(RobotModel.__args__) == set(ROBOTS)  # type: ignore[attr-defined]

Joints = Annotated[list[Angle], Field(min_length=6, max_length=6)]


class Limits(Strict):
    """Motion limits plans may use, never above the controller's (checked per model)."""

    joint_speed: AngularSpeed | Annotated[list[AngularSpeed], Field(min_length=6, max_length=6)] | None = None
    joint_accel: AngularAccel | Annotated[list[AngularAccel], Field(min_length=6, max_length=6)] | None = None
    tcp_speed: Speed | None = None
    margin: Fraction = 0.95


class Robot(Strict):
    model: RobotModel
    host: str | None = None
    backend: Literal["ur", "sim"] = "ur"
    mount: Pose = Field(default_factory=Pose)
    home: Joints
    limits: Limits = Field(default_factory=Limits)
    tool: Name | None = None  # with ``tools:``, the one mounted at start


class Payload(Strict):
    mass: Mass = 0.0
    cog: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class OutputValue(Strict):
    output: Name
    value: bool | float = True


class Cup(Strict):
    """A suction cup: its face centre in the TCP frame (m) and its radius (m)."""

    xyz: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    radius: PositiveLength = 0.02


class BlowOff(Strict):
    output: Name
    pulse: PositiveDuration = 0.1  # s


class Gripper(Strict):
    kind: Literal["io", "robotiq", "vacuum"] = "io"
    close: OutputValue | None = None
    open: OutputValue | None = None
    closed_sensor: Name | None = None
    open_sensor: Name | None = None
    stroke: PositiveLength = 0.085
    close_time: PositiveDuration = 0.2  # s, jaws from fully open to closed (datasheet)
    host: str | None = None  # robotiq socket host (default: the robot host)
    port: int = Field(default=63352, ge=1, le=65535)
    # kind: vacuum
    suction: OutputValue | None = None
    vacuum_ok: Name | None = None
    blow_off: BlowOff | None = None
    cups: list[Cup] = Field(default_factory=list)
    holding_force: Force | None = None  # N, the pull the cups hold before the part tears off


class Tool(Strict):
    tcp: Pose = Field(default_factory=Pose)
    payload: Payload = Field(default_factory=Payload)
    gripper: Gripper | None = None
    geometry: list[PlacedShape] = Field(default_factory=list)


class ToolChanger(Strict):
    """``lock`` output locks the mounted tool, ``locked`` input confirms it; ``rack`` gives
    each tool's rack frame (the TCP pose of that tool parked in the rack)."""

    lock: Name
    locked: Name | None = None
    rack: dict[Name, Name] = Field(default_factory=dict)
    approach: PositiveLength = 0.1  # m, along the rack frame's Z


class Io(Strict):
    outputs: dict[Name, str] = Field(default_factory=dict)
    inputs: dict[Name, str] = Field(default_factory=dict)


class Fixture(PlacedShape):
    name: Name


class Frame(Pose):
    parent: Name = "world"


class Part(Shaped):
    name: Name
    mass: Mass
    at: Name
    friction: float = Field(default=0.8, gt=0, le=2)


class Modbus(Strict):
    bind: str = "127.0.0.1"
    port: int = Field(default=502, ge=1, le=65535)
    heartbeat_timeout: PositiveDuration = 1.5


SecurityPolicy = Literal[
    "none",
    "Basic256Sha256_Sign", "Basic256Sha256_SignAndEncrypt",
    "Aes128Sha256RsaOaep_Sign", "Aes128Sha256RsaOaep_SignAndEncrypt",
    "Aes256Sha256RsaPss_Sign", "Aes256Sha256RsaPss_SignAndEncrypt",
]


class OpcUa(Strict):
    endpoint: str = "opc.tcp://127.0.0.1:4840/cellrunner"
    security: list[SecurityPolicy] = Field(
        default_factory=lambda: ["Basic256Sha256_SignAndEncrypt"], min_length=1)
    users: str | None = None
    pki: str | None = None

    @field_validator("endpoint")
    @classmethod
    def _endpoint(cls, v: str) -> str:
        if not v.startswith("opc.tcp://"):
            from pydantic_core import PydanticCustomError
            raise PydanticCustomError("endpoint", f"endpoint {v!r} must start with opc.tcp://")
        return v


class Plc(Strict):
    modbus: Modbus | None = None
    opcua: OpcUa | None = None


class Cell(Strict):
    """A robot cell: robot, tool, IO, fixtures, frames, parts, tasks, PLC link, journal."""

    cell: Name
    robot: Robot
    tool: Tool = Field(default_factory=Tool)
    tools: dict[Name, Tool] = Field(default_factory=dict)
    tool_changer: ToolChanger | None = None
    io: Io = Field(default_factory=Io)
    fixtures: list[Fixture] = Field(default_factory=list)
    frames: dict[Name, Frame] = Field(default_factory=dict)
    parts: list[Part] = Field(default_factory=list)
    tasks: dict[Annotated[int, Field(ge=1, le=65535)], str] = Field(default_factory=dict)
    plc: Plc = Field(default_factory=Plc)
    journal: str = "var/jobs.sqlite"
    step_timeout: PositiveDuration = 60.0

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

