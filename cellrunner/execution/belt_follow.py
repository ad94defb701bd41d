"""Following a belt whose speed changes, on the approved stretch (SPEC section 13).

A tracked stretch is made for the belt's measured speed: set-point ``k`` puts the arm
where the part is when the belt has carried it ``k`` periods at that speed. While the belt
keeps that line the stretch streams one set-point a period. When the belt slows, stops or
starts again, the arm is sent along the same approved path at the belt's pace instead: the
path position ``u`` (fractional set-points) goes where the belt's travel says the part is,
its rate (set-points a period) kept within the joints' speed and acceleration limits x
margin, so it slows, stands and starts again with the belt (a line's drive ramps its belt
down and up). Every commanded point lies on the approved path
(:func:`~cellrunner.model.trajectory.along_path`). A belt that changes faster than the arm
can follow (stopped at once, jumped: an encoder fault) leaves the arm more than
``BELT_TOLERANCE_M`` from the part: a controlled stop, the caller's.

Past the end of the tracked steps (the part lifted off the belt) the rest of the stretch
runs at its own pace, belt or no belt.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.trajectory import ApprovedTrajectory, along_path

if TYPE_CHECKING:
    from cellrunner.planning.timing import MotionLimits
    from cellrunner.planning.tracked_approval import TrackedRun

#: the belt may leave the line of its measured speed by this much, m, before the arm
#: follows its travel rather than the clock: above an encoder's quarter-mm ticks and the
#: few periods by which a controller's relayed count can trail its clock under load
FOLLOW_FROM_M = 0.002
#: how much of each period's new belt rate the estimate takes (the ticks' noise smoothed)
RATE_GAIN = 0.2
#: the most set-points a period the arm may run ahead at while it catches up, if the limits
#: allow (the engine, behind a controller's time, sends two as the nominal stream does)
MAX_RATE = 2.0


@dataclass
class Command:
    """One period's set-point: ``trajectory``'s sample ``index`` (the approved stretch's
    own, or a two-sample piece of its path), where on the stretch that is (``u``), how far
    the arm is behind the part (``lag_m``, negative: ahead) and whether the engine came
    late to this period (``late``: more than two periods since the last, so the lag is
    the engine's, which the set-points catch up, not the belt's)."""

    trajectory: ApprovedTrajectory
    index: int
    u: float
    lag_m: float
    late: bool


class BeltFollower:
    """The path position of the stretch ``run`` the arm is sent to each period, from the
    belt's measured travel; see the module docstring."""

    def __init__(self, run: TrackedRun, limits: MotionLimits, u: float, rate: float) -> None:
        self.run = run
        traj = run.approved.trajectory
        dt = 1.0 / traj.rate_hz
        q = traj.q_rad
        q_u = np.gradient(q, axis=0) if len(q) > 1 else np.zeros_like(q)
        q_uu = np.gradient(q_u, axis=0) if len(q) > 1 else np.zeros_like(q)
        self._q_u, self._q_uu = np.abs(q_u), np.abs(q_uu)  # rad a sample, a sample^2
        self._dt = dt
        self._v_lim = np.asarray(limits.joint_speed_rad_s) * dt  # rad a period
        self._a_lim = np.asarray(limits.joint_accel_rad_s2) * dt * dt  # rad a period^2
        self._sample_m = run.speed_mps * dt  # the belt's travel one set-point stands for
        self._last = len(q) - 1
        self._follow_to = max((end for _, _, end in run.spans), default=0)
        self.u, self.rate = float(u), float(rate)
        self._belt_rate = float(rate)
        self._s_last: float | None = None
        self._t_last: float | None = None

    @property
    def at_end(self) -> bool:
        return self.u >= self._last - 1e-9

    def next(self, offset_m: float, now_s: float) -> Command:
        """The set-point for the coming period with the part at ``offset_m`` from the frame
        at ``now_s`` (the belt's travel as measured, the backend's time)."""
        periods = 1 if self._t_last is None else round((now_s - self._t_last) / self._dt)
        self._t_last = now_s
        if self._s_last is not None and self._sample_m > 0 and periods > 0:
            moved = (offset_m - self._s_last) / self._sample_m / periods
            self._belt_rate += RATE_GAIN * (moved - self._belt_rate)
        self._s_last = offset_m
        u0 = self.u
        lag = 0.0
        if u0 < self._follow_to:
            # how far the part is past the set-point sent last (there while the belt keeps
            # the stretch's speed; the next one is reached a period later); before the
            # stretch starts, past its start
            lag = offset_m - self.run.start_m - u0 * self._sample_m
            lag = max(lag, 0.0) if u0 == 0.0 else lag
        if u0 < self._follow_to and self._sample_m > 0:
            target = (offset_m - self.run.start_m) / self._sample_m + max(self._belt_rate, 0.0)
        else:  # off the belt (or a stretch made for a standing belt): its own pace
            target = u0 + 1.0
        self.rate = self._rate_toward(target - u0, max(periods, 1))
        self.u = min(u0 + self.rate, float(self._last))
        late = periods > 2
        if self.rate == 1.0 and float(u0).is_integer():
            return Command(self.run.approved, int(self.u), self.u, lag, late)
        piece = along_path(self.run.approved, np.array([u0, self.u]))
        return Command(piece, 1, self.u, lag, late)

    def _rate_toward(self, wanted: float, periods: int) -> float:
        """The rate nearest ``wanted`` that the joints allow from the current one here,
        ``periods`` periods after it was set: speed ``q_u * r`` and acceleration
        ``q_uu * r^2 + q_u * dr`` within the limits."""
        i = min(int(self.u), self._last)
        q_u, q_uu = self._q_u[i], self._q_uu[i]
        moving = q_u > 1e-12
        r_top = MAX_RATE
        if moving.any():
            r_top = min(r_top, float(np.min(self._v_lim[moving] / q_u[moving])))
        r = self.rate
        room = self._a_lim - q_uu * r * r
        dr = float(np.min(np.maximum(room[moving], 0.0) / q_u[moving])) if moving.any() else 1.0
        dr *= periods
        return float(np.clip(wanted, max(0.0, r - dr), max(0.0, min(r_top, r + dr))))
