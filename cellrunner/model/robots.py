"""The Universal Robots arms cellrunner supports, as data.

Sources:
- DH parameters: Universal Robots, "DH parameters for calculations of kinematics and
  dynamics" (universal-robots.com support article, CB3 and e-Series tables). The DH base
  frame is the controller's ``base`` frame (the frame of its TCP poses) and DH frame 6 is
  the flange (``tool0``); the same convention as ur-analytic-ik, checked in the tests.
- Joint speed limits: the arms' technical specifications (datasheets): UR3/UR3e
  180 deg/s on base, shoulder and elbow, 360 deg/s on the wrists; UR5/UR5e 180 deg/s on
  every joint; UR10/UR10e/UR16e 120 deg/s on base and shoulder, 180 deg/s elsewhere.
- Joint ranges: +-360 deg on every joint (UR3/UR3e wrist 3 is infinite on the arm; we
  keep +-360 deg so a plan never winds the cable-free joint without bound).
- Joint acceleration and TCP speed caps: the largest values the controller accepts for
  ``movej``/``servoj`` and ``movel`` commands through ur_rtde (40 rad/s^2, 3 m/s).
- Controller rate: 125 Hz on CB3, 500 Hz on e-Series (RTDE and servoj period).
- Reach and payload: datasheets. Lateral link offsets (``shoulder_offset``,
  ``elbow_offset``): ur_description's physical parameters, for collision capsules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

JOINT_NAMES = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow",
    "wrist_1",
    "wrist_2",
    "wrist_3",
)
DH_ALPHA_RAD = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
JOINT_ACCEL_MAX_DEG_S2 = math.degrees(40.0)
TCP_SPEED_MAX_MPS = 3.0


@dataclass(frozen=True)
class Capsule:
    """A collision capsule fixed to body ``body`` (0 = base, i = moved by joint i).

    ``p0_m`` and ``p1_m`` are the segment ends in the body frame: the base frame for
    body 0, otherwise DH frame i-1 turned by joint i (before the DH offsets d_i, a_i).
    """

    body: int
    p0_m: tuple[float, float, float]
    p1_m: tuple[float, float, float]
    radius_m: float


@dataclass(frozen=True)
class RobotSpec:
    """One arm model: kinematics, limits and controller facts (SI, degrees)."""

    name: str
    generation: str  # "CB3" | "e-Series"
    d_m: tuple[float, ...]  # DH d, 6 values
    a_m: tuple[float, ...]  # DH a, 6 values
    joint_speed_max_deg_s: tuple[float, ...]
    reach_m: float
    payload_max_kg: float
    shoulder_offset_m: float
    elbow_offset_m: float
    link_radius_m: float  # upper arm radius; the others scale from it
    joint_min_deg: tuple[float, ...] = (-360.0,) * 6
    joint_max_deg: tuple[float, ...] = (360.0,) * 6
    joint_accel_max_deg_s2: float = JOINT_ACCEL_MAX_DEG_S2
    tcp_speed_max_mps: float = TCP_SPEED_MAX_MPS

    @property
    def rate_hz(self) -> float:
        """Controller cycle rate: 500 Hz e-Series, 125 Hz CB3."""
        return 500.0 if self.generation == "e-Series" else 125.0

    @property
    def alpha_rad(self) -> tuple[float, ...]:
        return DH_ALPHA_RAD

    def capsules(self) -> tuple[Capsule, ...]:
        """Collision capsules of the arm from base to flange (see :class:`Capsule`)."""
        d1, a2, a3, d4, d5, d6 = self.d_m[0], self.a_m[1], self.a_m[2], *self.d_m[3:]
        r = self.link_radius_m
        s = self.shoulder_offset_m  # upper-arm axis, lateral along the joint-2 axis
        f = s - self.elbow_offset_m  # forearm axis
        return (
            Capsule(0, (0, 0, 0.0), (0, 0, d1 - 1.2 * r), 1.25 * r),
            Capsule(1, (0, 0, d1), (0, -s, d1), 1.25 * r),
            Capsule(2, (0, 0, s), (a2, 0, s), r),
            Capsule(3, (0, 0, f), (0, 0, s), 0.95 * r),
            Capsule(3, (0, 0, f), (a3, 0, f), 0.85 * r),
            Capsule(4, (0, 0, f), (0, 0, d4), 0.75 * r),
            Capsule(5, (0, 0, 0), (0, 0, d5), 0.75 * r),
            Capsule(6, (0, 0, 0), (0, 0, d6 - 0.25 * r), 0.75 * r),
        )

    #: Body pairs that touch by construction and are never checked against each other.
    ALLOWED_SELF_CONTACT = frozenset(
        {(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (4, 6), (0, 2)}
    )


def _deg(*v: float) -> tuple[float, ...]:
    return tuple(float(x) for x in v)


ROBOTS: dict[str, RobotSpec] = {
    spec.name: spec
    for spec in (
        RobotSpec(
            "ur3",
            "CB3",
            d_m=(0.1519, 0, 0, 0.11235, 0.08535, 0.0819),
            a_m=(0, -0.24365, -0.21325, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 360, 360, 360),
            reach_m=0.50,
            payload_max_kg=3.0,
            shoulder_offset_m=0.1198,
            elbow_offset_m=0.0925,
            link_radius_m=0.045,
        ),
        RobotSpec(
            "ur5",
            "CB3",
            d_m=(0.089159, 0, 0, 0.10915, 0.09465, 0.0823),
            a_m=(0, -0.425, -0.39225, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 180, 180, 180),
            reach_m=0.85,
            payload_max_kg=5.0,
            shoulder_offset_m=0.13585,
            elbow_offset_m=0.1197,
            link_radius_m=0.06,
        ),
        RobotSpec(
            "ur10",
            "CB3",
            d_m=(0.1273, 0, 0, 0.163941, 0.1157, 0.0922),
            a_m=(0, -0.612, -0.5723, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=1.30,
            payload_max_kg=10.0,
            shoulder_offset_m=0.220941,
            elbow_offset_m=0.1719,
            link_radius_m=0.075,
        ),
        RobotSpec(
            "ur3e",
            "e-Series",
            d_m=(0.15185, 0, 0, 0.13105, 0.08535, 0.0921),
            a_m=(0, -0.24355, -0.2132, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 360, 360, 360),
            reach_m=0.50,
            payload_max_kg=3.0,
            shoulder_offset_m=0.120,
            elbow_offset_m=0.093,
            link_radius_m=0.045,
        ),
        RobotSpec(
            "ur5e",
            "e-Series",
            d_m=(0.1625, 0, 0, 0.1333, 0.0997, 0.0996),
            a_m=(0, -0.425, -0.3922, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 180, 180, 180),
            reach_m=0.85,
            payload_max_kg=5.0,
            shoulder_offset_m=0.138,
            elbow_offset_m=0.131,
            link_radius_m=0.06,
        ),
        RobotSpec(
            "ur10e",
            "e-Series",
            d_m=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
            a_m=(0, -0.6127, -0.57155, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=1.30,
            payload_max_kg=12.5,
            shoulder_offset_m=0.176,
            elbow_offset_m=0.137,
            link_radius_m=0.075,
        ),
        RobotSpec(
            "ur16e",
            "e-Series",
            d_m=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
            a_m=(0, -0.4784, -0.36, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=0.90,
            payload_max_kg=16.0,
            shoulder_offset_m=0.176,
            elbow_offset_m=0.137,
            link_radius_m=0.075,
        ),
    )
}


def robot_spec(name: str) -> RobotSpec:
    """The spec of model ``name``; unknown names raise KeyError listing the known ones."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise KeyError(f"unknown robot model {name!r}; known: {', '.join(ROBOTS)}") from None
