"""The Universal Robots arms cellrunner supports, as data: every arm ur-analytic-ik solves.

Sources, per figure:

- DH parameters (d, a; alpha is the same on every arm): Universal Robots, "DH parameters
  for calculations of kinematics and dynamics" (universal-robots.com support article), the
  table ur-analytic-ik compiles in (its ``dh_parameters.hh``). The DH base frame is the
  controller's ``base`` frame and DH frame 6 is the flange (``tool0``); forward kinematics
  is checked against ur-analytic-ik for every model in the tests. UR7e and UR12e are the
  UR5e and UR10e renamed (2025), with the same kinematics.
- Joint speed limits and joint ranges: the arms' user manuals and datasheets, as
  transcribed in Universal Robots' own ``ur_description`` package
  (``config/<model>/joint_limits.yaml``, ``max_velocity`` in deg/s):
  UR3/UR3e 180 deg/s on base, shoulder and elbow, 360 deg/s on the wrists; UR5/UR5e/UR7e
  180 deg/s everywhere; UR10/UR10e/UR12e/UR16e 120 deg/s on base and shoulder, 180 deg/s
  elsewhere; UR18 180/180/240 deg/s and 300 deg/s on the wrists; UR20/UR30 120/120/150
  deg/s and 210 deg/s on the wrists. Every joint of every arm ranges over +-360 deg (UR3
  and UR3e wrist 3 turns without end; we keep +-360 deg so a plan never winds it without
  bound). ur_description narrows the elbow to +-180 deg for MoveIt's sake; the datasheets
  give +-360 deg and so do we (the collision model keeps the elbow off the upper arm).
- NOT VERIFIED: no joint_limits file or datasheet text for the UR15 and the UR8 Long was
  available. Their joint speeds are set to the slowest published UR Series figures (the
  UR20/UR30's 120/120/150/210/210/210 deg/s), an assumption on the safe side: plans may
  run slower than the arm can, never faster. Their ranges (+-360 deg) are assumed too.
- Reach and payload: datasheets (CB3, UR3e/UR5e/UR10e/UR16e). For UR7e 7.5 kg / 850 mm,
  UR12e 12.5 kg / 1300 mm, UR15 1300 mm, UR18 18 kg / 950 mm, UR20 1750 mm, UR30
  1300 mm and UR8 Long 1750 mm the figures come from a third-party summary of UR's model
  table, not from UR's datasheet text. Payloads are the nominal ones of the model names
  (UR15 15 kg, UR20 20 kg, UR30 30 kg, UR8 Long 8 kg); later software raised some of them
  (the same summary gives 17.5, 25, 35 and 10 kg), which we do not assume. The reach is
  only used in messages ("out of reach ... reach 0.85 m") and to scale the twin's inertia.
- Joint acceleration and TCP speed caps: the largest values the controller accepts for
  ``movej``/``servoj`` and ``movel`` commands through ur_rtde (40 rad/s^2, 3 m/s).
- Controller rate: 125 Hz on CB3, 500 Hz on the e-Series controller, which also runs the
  UR15/UR18/UR20/UR30/UR8 Long (``generation`` is the controller's: "CB3" or "e-Series").
- Collision geometry: derived from Universal Robots' collision meshes, per arm
  (:mod:`cellrunner.model.arm_geometry`), not from these figures.
- ``robot.joint_range`` (SPEC section 11) narrows the ranges per cell:
  :meth:`RobotSpec.narrowed`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
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
#: models that are another model's arm under a new name (see RobotSpec.arm)
RENAMED = {"ur7e": "ur5e", "ur12e": "ur10e"}
TCP_SPEED_MAX_MPS = 3.0


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
    joint_min_deg: tuple[float, ...] = (-360.0,) * 6
    joint_max_deg: tuple[float, ...] = (360.0,) * 6
    joint_accel_max_deg_s2: float = JOINT_ACCEL_MAX_DEG_S2
    tcp_speed_max_mps: float = TCP_SPEED_MAX_MPS

    @property
    def rate_hz(self) -> float:
        """Controller cycle rate: 500 Hz e-Series, 125 Hz CB3."""
        return 500.0 if self.generation == "e-Series" else 125.0

    @property
    def arm(self) -> str:
        """The physical arm: UR7e and UR12e are the UR5e and UR10e renamed (2025), the same
        links and meshes; anything looked up per arm (collision geometry, twin masses) uses it."""
        return RENAMED.get(self.name, self.name)

    @property
    def label(self) -> str:
        """The model as Universal Robots writes it: ``UR5e``, ``UR20``, ``UR8 Long``."""
        return "UR8 Long" if self.name == "ur8long" else self.name.upper().replace("E", "e")

    @property
    def joint_range_narrowed(self) -> bool:
        """Whether a cell's ``joint_range`` narrowed the hardware ranges of this spec."""
        hardware = ROBOTS.get(self.name)
        return hardware is not None and (
            self.joint_min_deg != hardware.joint_min_deg
            or self.joint_max_deg != hardware.joint_max_deg
        )

    def narrowed(self, joint_range_deg: Sequence[Sequence[float]] | None) -> RobotSpec:
        """This arm with the joint ranges narrowed to ``joint_range_deg`` (6 x [min, max],
        deg, SPEC section 11 ``robot.joint_range``); None: unchanged. The caller has checked
        that every range lies inside the hardware's and has min < max."""
        if joint_range_deg is None:
            return self
        return dataclasses.replace(
            self,
            joint_min_deg=tuple(float(lo) for lo, _ in joint_range_deg),
            joint_max_deg=tuple(float(hi) for _, hi in joint_range_deg),
        )

    @property
    def alpha_rad(self) -> tuple[float, ...]:
        return DH_ALPHA_RAD


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
        ),
        RobotSpec(
            "ur5",
            "CB3",
            d_m=(0.089159, 0, 0, 0.10915, 0.09465, 0.0823),
            a_m=(0, -0.425, -0.39225, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 180, 180, 180),
            reach_m=0.85,
            payload_max_kg=5.0,
        ),
        RobotSpec(
            "ur10",
            "CB3",
            d_m=(0.1273, 0, 0, 0.163941, 0.1157, 0.0922),
            a_m=(0, -0.612, -0.5723, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=1.30,
            payload_max_kg=10.0,
        ),
        RobotSpec(
            "ur3e",
            "e-Series",
            d_m=(0.15185, 0, 0, 0.13105, 0.08535, 0.0921),
            a_m=(0, -0.24355, -0.2132, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 360, 360, 360),
            reach_m=0.50,
            payload_max_kg=3.0,
        ),
        RobotSpec(
            "ur5e",
            "e-Series",
            d_m=(0.1625, 0, 0, 0.1333, 0.0997, 0.0996),
            a_m=(0, -0.425, -0.3922, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 180, 180, 180),
            reach_m=0.85,
            payload_max_kg=5.0,
        ),
        RobotSpec(
            "ur7e",
            "e-Series",
            d_m=(0.1625, 0, 0, 0.1333, 0.0997, 0.0996),
            a_m=(0, -0.425, -0.3922, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 180, 180, 180, 180),
            reach_m=0.85,
            payload_max_kg=7.5,
        ),
        RobotSpec(
            "ur10e",
            "e-Series",
            d_m=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
            a_m=(0, -0.6127, -0.57155, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=1.30,
            payload_max_kg=12.5,
        ),
        RobotSpec(
            "ur16e",
            "e-Series",
            d_m=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
            a_m=(0, -0.4784, -0.36, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=0.90,
            payload_max_kg=16.0,
        ),
        RobotSpec(
            "ur12e",
            "e-Series",
            d_m=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
            a_m=(0, -0.6127, -0.57155, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 180, 180, 180, 180),
            reach_m=1.30,
            payload_max_kg=12.5,
        ),
        RobotSpec(
            "ur15",
            "e-Series",
            d_m=(0.2186, 0, 0, 0.1824, 0.1361, 0.1434),
            a_m=(0, -0.6475, -0.5164, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 150, 210, 210, 210),  # not verified
            reach_m=1.30,
            payload_max_kg=15.0,
        ),
        RobotSpec(
            "ur18",
            "e-Series",
            d_m=(0.2186, 0, 0, 0.1824, 0.1361, 0.1434),
            a_m=(0, -0.475, -0.3389, 0, 0, 0),
            joint_speed_max_deg_s=_deg(180, 180, 240, 300, 300, 300),
            reach_m=0.95,
            payload_max_kg=18.0,
        ),
        RobotSpec(
            "ur20",
            "e-Series",
            d_m=(0.2363, 0, 0, 0.2010, 0.1593, 0.1543),
            a_m=(0, -0.8620, -0.7287, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 150, 210, 210, 210),
            reach_m=1.75,
            payload_max_kg=20.0,
        ),
        RobotSpec(
            "ur30",
            "e-Series",
            d_m=(0.2363, 0, 0, 0.2010, 0.1593, 0.1543),
            a_m=(0, -0.6370, -0.5037, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 150, 210, 210, 210),
            reach_m=1.30,
            payload_max_kg=30.0,
        ),
        RobotSpec(
            "ur8long",
            "e-Series",
            d_m=(0.2186, 0, 0, 0.1824, 0.1361, 0.1434),
            a_m=(0, -0.8989, -0.7149, 0, 0, 0),
            joint_speed_max_deg_s=_deg(120, 120, 150, 210, 210, 210),  # not verified
            reach_m=1.75,
            payload_max_kg=8.0,
        ),
    )
}


def robot_spec(name: str) -> RobotSpec:
    """The spec of model ``name``; unknown names raise KeyError listing the known ones."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise KeyError(f"unknown robot model {name!r}; known: {', '.join(ROBOTS)}") from None
