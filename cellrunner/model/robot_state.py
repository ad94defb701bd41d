"""What the engine knows of the robot from one controller cycle: its safety state
(:class:`Safety`, UR's safety modes as the engine collapses them) and its measurements
(:class:`RobotState`). The robot backends report in these terms, the twin and the
simulator speak them, the execution engine acts on them."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


class Safety(enum.Enum):
    """Controller safety state, as UR's safety modes collapse for the engine."""

    NORMAL = "normal"
    PROTECTIVE_STOP = "protective_stop"
    EMERGENCY_STOP = "emergency_stop"  # robot or system e-stop pressed
    FAULT = "fault"  # violation / fault: needs restart safety
    DISCONNECTED = "disconnected"


@dataclass(frozen=True)
class RobotState:
    """One controller cycle's measurements.

    ``wrench_N`` is force (N) and torque (N m) at the tool flange, in the base frame, as
    UR's ``actual_TCP_force`` reports it. ``inputs`` and ``outputs`` are keyed by channel
    (``DI0``, ``TI1``, ``DO3``...); analog channels carry floats.
    """

    time_s: float
    q_rad: np.ndarray
    qd_rad_s: np.ndarray
    wrench_N: np.ndarray
    safety: Safety
    inputs: dict[str, float | bool] = field(default_factory=dict)
    outputs: dict[str, float | bool] = field(default_factory=dict)
    powered: bool = True
    brakes_released: bool = True
