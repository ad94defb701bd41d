"""The cell file (SPEC section 3) as pydantic models. Pure data; references are
checked in :mod:`cellrunner.model.references`."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator

from cellrunner.model.base import Name, PlacedShape, Pose, Shaped, Strict, Vec3
from cellrunner.model.robots import ROBOTS
from cellrunner.model.sim_inputs import SimBlock
from cellrunner.model.units import (
    Angle, AngularAccel, AngularSpeed, Duration, Fraction, Mass, PositiveDuration,
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


class Payload(Strict):
    mass: Mass = 0.0
    cog: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class OutputValue(Strict):
    output: Name
    value: bool | float = True


class Gripper(Strict):
    kind: Literal["io", "robotiq"] = "io"
    close: OutputValue | None = None
    open: OutputValue | None = None
    closed_sensor: Name | None = None
    open_sensor: Name | None = None
    stroke: PositiveLength = 0.085
    close_time: PositiveDuration = 0.2  # s, jaws from fully open to closed (datasheet)
    host: str | None = None  # robotiq socket host (default: the robot host)
    port: int = Field(default=63352, ge=1, le=65535)


class Tool(Strict):
    tcp: Pose = Field(default_factory=Pose)
    payload: Payload = Field(default_factory=Payload)
    gripper: Gripper | None = None
    geometry: list[PlacedShape] = Field(default_factory=list)


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
    offset: Pose | None = None  # twin only: where the part really lies from ``at`` (a camera's find)
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


class PlaceTolerance(Strict):
    """How far a placed part may end from its target before the twin calls the place
    failed (SPEC section 11): ``distance`` m, ``angle`` deg."""

    distance: PositiveLength = 0.005
    angle: Annotated[Angle, Field(gt=0)] = 5.0


class Cell(Strict):
    """A robot cell: robot, tool, IO, fixtures, frames, parts, tasks, PLC link, journal."""

    cell: Name
    robot: Robot
    tool: Tool = Field(default_factory=Tool)
    io: Io = Field(default_factory=Io)
    fixtures: list[Fixture] = Field(default_factory=list)
    frames: dict[Name, Frame] = Field(default_factory=dict)
    parts: list[Part] = Field(default_factory=list)
    tasks: dict[Annotated[int, Field(ge=1, le=65535)], str] = Field(default_factory=dict)
    plc: Plc = Field(default_factory=Plc)
    journal: str = "var/jobs.sqlite"
    step_timeout: PositiveDuration = 60.0
    place_tolerance: PlaceTolerance = Field(default_factory=PlaceTolerance)
    sim: SimBlock | None = None  # inputs the twin drives in rehearsal
