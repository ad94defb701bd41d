"""Servo: the arm follows a stream of velocity commands (a person on a device, or a
program over UDP), one tick per controller period.

Each tick (:meth:`Servo.step`) takes the latest :class:`Command` and turns it into the
joint speeds to send:

1. a command older than :data:`TIMEOUT_S` counts as none: the arm brakes to a stop;
2. the dead band zeroes components slower than :data:`DEAD_BAND_MPS` /
   :data:`DEAD_BAND_RAD_S` (devices add their own, on the stick's travel);
3. the jog's governor (:class:`cellrunner.commissioning.jog.Governor`: singularities,
   fixtures, joint limits, the watched zone) scales the requested motion;
4. a jerk-limited filter (Ruckig, velocity interface, phase-synchronised so that every
   component ramps in proportion and a straight line stays straight) smooths it;
5. Cartesian velocities become joint speeds through the damped inverse of the TCP
   Jacobian at the measured joints, capped uniformly at the cell's joint speed limits.

Frames: ``base`` is the controller's base frame, ``tool`` the TCP frame; twists are
linear m/s then angular rad/s. ``joint`` commands are six joint speeds, rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.commissioning import jog

if TYPE_CHECKING:
    from cellrunner.planning.world import CellWorld

#: a command older than this stops the arm (s)
TIMEOUT_S = 0.1
#: slower components than these are zero (m/s, rad/s)
DEAD_BAND_MPS = 0.001
DEAD_BAND_RAD_S = math.radians(0.1)
#: the smoothing filter's limits: linear m/s^2 and m/s^3; angular and joint rad/s^2, rad/s^3
LINEAR_ACCEL_MPS2, LINEAR_JERK_MPS3 = 1.0, 20.0
ANGULAR_ACCEL_RAD_S2, ANGULAR_JERK_RAD_S3 = math.radians(180.0), math.radians(3600.0)
#: command speed ceilings (the jog's full speeds): faster commands are scaled down whole
MAX_LINEAR_MPS = jog.LINEAR_SPEED_MPS
MAX_ANGULAR_RAD_S = math.radians(jog.ANGULAR_SPEED_DEG_S)
MAX_JOINT_RAD_S = math.radians(jog.JOINT_SPEED_DEG_S)
FRAMES = ("base", "tool", "joint")


@dataclass(frozen=True)
class Command:
    """One velocity command: ``frame`` base | tool (a twist, m/s and rad/s) or joint
    (six joint speeds, rad/s), received at ``t_s`` (monotonic clock)."""

    frame: str
    velocity: tuple[float, ...]
    t_s: float

    def capped(self) -> Command:
        """This command scaled down whole (direction kept) to the jog's full speeds."""
        v = np.asarray(self.velocity, float)
        if self.frame == "joint":
            ratio = float(np.max(np.abs(v))) / MAX_JOINT_RAD_S
        else:
            ratio = max(
                float(np.linalg.norm(v[:3])) / MAX_LINEAR_MPS,
                float(np.linalg.norm(v[3:])) / MAX_ANGULAR_RAD_S,
            )
        if ratio <= 1.0:
            return self
        return Command(self.frame, tuple(float(x) for x in v / ratio), self.t_s)


@dataclass(frozen=True)
class Tick:
    """What one servo tick decided: joint speeds to send (rad/s) and why."""

    qd_rad_s: np.ndarray
    frame: str  # the frame the filter is moving in
    velocity: np.ndarray  # the smoothed command, in ``frame``
    verdict: jog.Verdict | None  # None when nothing was asked
    commanded: bool  # a fresh command was there


def dead_band(frame: str, velocity: np.ndarray) -> np.ndarray:
    """``velocity`` with the components inside the dead band set to zero."""
    v = np.array(velocity, float)
    band = np.full(6, DEAD_BAND_RAD_S)
    if frame != "joint":
        band[:3] = DEAD_BAND_MPS
    v[np.abs(v) < band] = 0.0
    return v


class Smoother:
    """Jerk-limited velocity filter over six components (Ruckig's velocity interface).

    A change of frame first brakes to a stop in the old frame, then starts in the new."""

    def __init__(self, period_s: float) -> None:
        from ruckig import (
            ControlInterface,
            InputParameter,
            OutputParameter,
            Ruckig,
            Synchronization,
        )

        self._otg = Ruckig(6, period_s)
        self._in, self._out = InputParameter(6), OutputParameter(6)
        self._in.control_interface = ControlInterface.Velocity
        self._in.synchronization = Synchronization.Phase
        self._in.current_position = [0.0] * 6
        self._in.current_velocity = [0.0] * 6
        self._in.current_acceleration = [0.0] * 6
        self._in.target_acceleration = [0.0] * 6
        self.frame = "base"
        self._set_limits(self.frame)

    def _set_limits(self, frame: str) -> None:
        if frame == "joint":
            accel, jerk = [ANGULAR_ACCEL_RAD_S2] * 6, [ANGULAR_JERK_RAD_S3] * 6
        else:
            accel = [LINEAR_ACCEL_MPS2] * 3 + [ANGULAR_ACCEL_RAD_S2] * 3
            jerk = [LINEAR_JERK_MPS3] * 3 + [ANGULAR_JERK_RAD_S3] * 3
        self._in.max_acceleration, self._in.max_jerk = accel, jerk

    @property
    def moving(self) -> bool:
        return bool(np.any(np.abs(self._in.current_velocity) > 1e-9))

    def update(self, frame: str, target: np.ndarray) -> np.ndarray:
        """One period towards ``target`` (in ``frame``): the velocity to command, in
        :attr:`frame` (which is still the old frame while braking)."""
        if frame != self.frame:
            if self.moving:
                target = np.zeros(6)
            else:
                self.frame = frame
                self._set_limits(frame)
        self._in.target_velocity = [float(x) for x in target]
        self._in.current_position = [0.0] * 6  # positions are not followed, only speeds
        self._otg.update(self._in, self._out)
        self._out.pass_to_input(self._in)
        velocity = np.array(self._out.new_velocity, float)
        if not np.any(target) and np.max(np.abs(velocity)) < 1e-7:
            self.reset()  # settled at rest: exactly zero from here
            return np.zeros(6)
        return velocity

    def reset(self) -> None:
        """At rest now (the arm was stopped by other means)."""
        self._in.current_velocity = [0.0] * 6
        self._in.current_acceleration = [0.0] * 6


class Servo:
    """Commands in, joint speeds out, one :meth:`step` per controller period."""

    def __init__(self, world: CellWorld, governor: jog.Governor | None = None) -> None:
        self.kinematics = world.kinematics
        self.governor = governor or jog.Governor(world.kinematics, world.collision)
        self.period_s = 1.0 / world.spec.rate_hz
        self.qd_max_rad_s = np.asarray(world.limits.joint_speed_rad_s, float)
        self.smoother = Smoother(self.period_s)

    def joint_speeds(self, q_rad: np.ndarray, frame: str, velocity: np.ndarray) -> np.ndarray:
        """Joint speeds (rad/s) giving ``velocity`` in ``frame`` at ``q_rad``."""
        if frame == "joint":
            return np.asarray(velocity, float)
        return jog.twist_qd(self.kinematics, q_rad, frame, velocity)

    def step(self, q_rad: np.ndarray, command: Command | None, now_s: float) -> Tick:
        q = np.asarray(q_rad, float)
        fresh = command is not None and now_s - command.t_s <= TIMEOUT_S
        frame, target = self.smoother.frame, np.zeros(6)
        verdict = None
        if fresh:
            assert command is not None
            frame = command.frame
            target = dead_band(frame, np.asarray(command.capped().velocity, float))
            if np.any(target):
                verdict = self.governor.judge(q, self.joint_speeds(q, frame, target))
                target = target * verdict.scale
        velocity = self.smoother.update(frame, target)
        qd = self.joint_speeds(q, self.smoother.frame, velocity)
        over = float(np.max(np.abs(qd) / self.qd_max_rad_s))
        if over > 1.0:
            qd = qd / over
        return Tick(qd, self.smoother.frame, velocity, verdict, fresh)
