"""How the arm takes up and gives back a belt's motion (SPEC section 13, ``track`` and
``untrack``): the belt offset ``sigma(t)`` (m along the conveyor's path) added to the
motion planned for a still part.

A ramp is a quintic in time that joins position, speed and acceleration at both ends,
so the commanded TCP has no step in speed or acceleration when tracking starts or ends:

- in (``track``): from ``sigma = 0`` at rest to the part, ``d0 + v T`` at the belt
  speed ``v`` (``d0``: where the part was, m from the conveyor's frame, when it started);
- out (``untrack``): from the part's offset at the belt speed back to ``sigma = 0`` at
  rest, so that the rest of the job starts where its plan starts.

A ramp's duration is the shortest of a growing sequence whose peak acceleration along
the path stays within its bounds (:func:`ramp_bounds`: ``RAMP_ACCEL_MPS2`` and
``RAMP_SPEED_MPS`` on a line; on a round table also what turns the wrist at most
``RAMP_TURN_RAD_S`` and ``RAMP_TURN_RAD_S2``); check then proves every joint's limits
along it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cellrunner.model.conveyor import Conveyor, ConveyorPath
    from cellrunner.planning.timing import MotionLimits

#: peak acceleration (m/s^2) along the belt's path a ramp may ask of the TCP, and peak
#: speed (m/s) beyond the belt's
RAMP_ACCEL_MPS2 = 2.0
RAMP_SPEED_MPS = 1.0
#: on a round table, the ramp turns the part (and the wrist following it) at most this
#: fast (rad/s) and this hard (rad/s^2)
RAMP_TURN_RAD_S = 0.8
RAMP_TURN_RAD_S2 = 3.0
#: the fraction of the joint limits (x margin) a tracked step's relative motion is timed
#: with: the rest is the belt's, whose motion adds to it (check proves the sum)
TRACKED_LIMIT_FRACTION = 0.75
#: the shortest ramp, s
RAMP_MIN_S = 0.25
#: a ramp's duration grows by this factor until it keeps to the bounds
RAMP_GROWTH = 1.15
#: ... at most this many times
RAMP_ROUNDS = 40
#: samples a ramp's peaks are measured on
RAMP_PROBE_SAMPLES = 64


@dataclass(frozen=True)
class Ramp:
    """``sigma(t)`` for ``0 <= t <= duration_s``: a quintic from (``s0_m``, ``v0_mps``, 0)
    to (``s1_m``, ``v1_mps``, 0)."""

    s0_m: float
    v0_mps: float
    s1_m: float
    v1_mps: float
    duration_s: float

    def coefficients(self) -> np.ndarray:
        """The quintic's coefficients c0..c5 in t (s)."""
        T = self.duration_s
        A = np.array(
            [
                [T**3, T**4, T**5],
                [3 * T**2, 4 * T**3, 5 * T**4],
                [6 * T, 12 * T**2, 20 * T**3],
            ]
        )
        b = np.array(
            [self.s1_m - self.s0_m - self.v0_mps * T, self.v1_mps - self.v0_mps, 0.0],
        )
        c3, c4, c5 = np.linalg.solve(A, b)
        return np.array([self.s0_m, self.v0_mps, 0.0, c3, c4, c5])

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(sigma m, its speed m/s, its acceleration m/s^2) at ``t_s`` (clipped to the ramp)."""
        c = self.coefficients()
        t = np.clip(np.asarray(t_s, float), 0.0, self.duration_s)
        s = np.polynomial.polynomial.polyval(t, c)
        v = np.polynomial.polynomial.polyval(t, c[1:] * np.arange(1, 6))
        a = np.polynomial.polynomial.polyval(t, c[2:] * np.array([2.0, 6.0, 12.0, 20.0]))
        return s, v, a

    def peaks(self) -> tuple[float, float]:
        """(largest |speed| m/s, largest |acceleration| m/s^2) along the ramp."""
        _, v, a = self.at(np.linspace(0.0, self.duration_s, RAMP_PROBE_SAMPLES))
        return float(np.abs(v).max()), float(np.abs(a).max())


@dataclass(frozen=True)
class RampBounds:
    """The peak speed (m/s) and acceleration (m/s^2) along the path a ramp may reach."""

    speed_mps: float = RAMP_SPEED_MPS
    accel_mps2: float = RAMP_ACCEL_MPS2


def ramp_bounds(path: ConveyorPath) -> RampBounds:
    """The bounds of a ramp along ``path``: on an arc, also those that keep the turn of
    the part (and of the wrist that follows it) gentle."""
    if path.arc is None:
        return RampBounds()
    r = float(path.arc.radius)
    return RampBounds(
        min(RAMP_SPEED_MPS, RAMP_TURN_RAD_S * r), min(RAMP_ACCEL_MPS2, RAMP_TURN_RAD_S2 * r)
    )


def _fitted(s0_m: float, v0_mps: float, end: _End, bounds: RampBounds) -> Ramp:
    T = RAMP_MIN_S
    for _ in range(RAMP_ROUNDS):
        s1, v1 = end(T)
        ramp = Ramp(s0_m, v0_mps, s1, v1, T)
        speed, accel = ramp.peaks()
        # catching up with a part ahead, or going back, at most this much faster than the belt
        if accel <= bounds.accel_mps2 and speed <= bounds.speed_mps + max(abs(v0_mps), abs(v1)):
            return ramp
        T *= RAMP_GROWTH
    return ramp


class _End:
    """Where a ramp of duration T ends: (sigma m, speed m/s)."""

    def __init__(self, s_m: float, v_mps: float, moving: bool) -> None:
        self.s_m, self.v_mps, self.moving = s_m, v_mps, moving

    def __call__(self, T: float) -> tuple[float, float]:
        if self.moving:  # onto a part that travels on while the ramp runs
            return self.s_m + self.v_mps * T, self.v_mps
        return self.s_m, 0.0


def ramp_in(d0_m: float, speed_mps: float, bounds: RampBounds | None = None) -> Ramp:
    """The ramp onto a part that is ``d0_m`` from the conveyor's frame, moving at
    ``speed_mps``, from the arm at rest at the frame."""
    return _fitted(0.0, 0.0, _End(d0_m, speed_mps, moving=True), bounds or RampBounds())


def ramp_out(s_m: float, speed_mps: float, bounds: RampBounds | None = None) -> Ramp:
    """The ramp from following a part at ``s_m`` (moving at ``speed_mps``) back to the
    frame, at rest."""
    return _fitted(s_m, speed_mps, _End(0.0, 0.0, moving=False), bounds or RampBounds())


def nominal_start_m(
    speed_mps: float, window_start_m: float, bounds: RampBounds | None = None
) -> float:
    """Where a part is, m from the frame, when the arm starts onto it at the earliest: half
    a speed ramp upstream, so that the arm meets it at the belt speed with no catch-up
    (never before the window starts)."""
    accel = (bounds or RampBounds()).accel_mps2
    T = max(RAMP_MIN_S, 1.875 * speed_mps / accel)  # a quintic's peak acceleration
    return max(window_start_m, -speed_mps * T / 2)


def worst_ramp_s(
    window_m: tuple[float, float], speed_max_mps: float, bounds: RampBounds | None = None
) -> float:
    """The longest ramp (in or out) anywhere in ``window_m`` at up to ``speed_max_mps``, s:
    what ``check`` counts in a cycle."""
    reach = max(abs(window_m[0]), abs(window_m[1]))
    return max(
        ramp_in(math.copysign(reach, window_m[1]), speed_max_mps, bounds).duration_s,
        ramp_out(reach, speed_max_mps, bounds).duration_s,
    )


def tracked_limits(limits: MotionLimits, speed_max_mps: float) -> MotionLimits:
    """The limits a step on a moving belt is planned with: a fraction of the joints'
    (``TRACKED_LIMIT_FRACTION``), and the TCP's cap less the belt's top speed."""
    from cellrunner.planning.timing import MotionLimits

    f = TRACKED_LIMIT_FRACTION
    return MotionLimits(
        limits.joint_speed_rad_s * f,
        limits.joint_accel_rad_s2 * f,
        max(0.05, limits.tcp_speed_mps - speed_max_mps),
    )


def conveyor_ramp_s(conveyor: Conveyor) -> float:
    """The longest ramp of ``conveyor`` (its window, its top speed, its path's bounds), s:
    what ``track`` and ``untrack`` count in a plan's cycle."""
    lo, hi = (float(w) for w in conveyor.window)
    return worst_ramp_s((lo, hi), float(conveyor.speed_max), ramp_bounds(conveyor.path))
