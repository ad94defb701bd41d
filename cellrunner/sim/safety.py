"""The controller's stops in the twin: why a stop happened, and the ramp that brings the
set-point to standstill (stopJ, a protective stop, the category 1 e-stop)."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

UNLOCK_DELAY_S = 5.0  # UR: a protective stop can be unlocked 5 s after it happened
STOP_DECEL_RAD_S2 = 30.0  # category 2 stop ramp (protective stop, stopJ default)
COLLISION_BACKOFF_S = 0.02  # after a collision the arm holds this much motion back


class StopReason(enum.StrEnum):
    CONTACT = "contact"
    INJECTED = "injected"
    REQUESTED = "requested"


@dataclass
class StopRamp:
    """A synchronized linear velocity ramp to standstill from ``qd0_rad_s``, begun at
    ``t0_s`` and lasting ``duration_s`` (simulated s)."""

    t0_s: float
    qd0_rad_s: np.ndarray
    duration_s: float

    @classmethod
    def from_speed(cls, t0_s: float, qd0_rad_s: np.ndarray, decel_rad_s2: float) -> StopRamp:
        """The ramp from ``qd0_rad_s`` that decelerates the fastest joint at ``decel_rad_s2``."""
        return cls(t0_s, qd0_rad_s, float(np.max(np.abs(qd0_rad_s))) / decel_rad_s2)

    def speed(self, t_s: float) -> np.ndarray:
        """Joint speeds (rad/s) at simulated time ``t_s``."""
        s = max(0.0, 1.0 - (t_s - self.t0_s) / self.duration_s) if self.duration_s > 0 else 0.0
        return self.qd0_rad_s * s
