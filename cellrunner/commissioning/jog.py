"""Jogging: keys held on a terminal become joint or Cartesian (base or tool frame)
velocities, streamed with speedJ at the controller rate, governed so that the arm slows
and then stops before a singularity or a fixture.

Dead-man: a terminal sends no key-up, only the key's auto-repeat; motion stops when no
repeat arrives within :data:`DEADMAN_S` (:data:`DEADMAN_FIRST_S` after the first press,
which the terminal repeats only after its initial delay).

Governing (named thresholds, checked at a look-ahead of the requested motion): speed is
scaled linearly from 1 at the SLOW threshold to 0 at the STOP threshold, and only for
motion that brings the arm closer; motion away is never held back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.model.body import BodyKind

if TYPE_CHECKING:
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.kinematics import ArmKinematics

#: dead-man: stop when no key repeat came within this long (s)
DEADMAN_S = 0.2
#: ... or this long after the first press (terminals repeat after ~0.25-0.5 s)
DEADMAN_FIRST_S = 0.6
#: full jog speed, scaled by the speed step
JOINT_SPEED_DEG_S = 30.0
LINEAR_SPEED_MPS = 0.25
ANGULAR_SPEED_DEG_S = 30.0
#: speed steps (fraction of full jog speed), ``+``/``-`` move between them
SPEED_STEPS = (0.1, 0.25, 0.5, 1.0)
#: speedJ acceleration (rad/s^2): ramps up and brakes
JOG_ACCEL_RAD_S2 = 2.0
#: wrist singularity: |q5| from 0/180 deg where jogging slows, and where it stops
WRIST_SLOW_DEG, WRIST_STOP_DEG = 20.0, 8.0
#: elbow singularity: |q3| from 0/180 deg (arm stretched out or folded)
ELBOW_SLOW_DEG, ELBOW_STOP_DEG = 15.0, 5.0
#: shoulder singularity: wrist point from the base-axis cylinder (m)
SHOULDER_SLOW_M, SHOULDER_STOP_M = 0.10, 0.04
#: clearance to fixtures and the arm itself beyond what the cell requires (m)
CLEARANCE_SLOW_M, CLEARANCE_STOP_M = 0.10, 0.02
#: joint limits: distance to the nearer end of a joint's range (deg)
JOINT_LIMIT_SLOW_DEG, JOINT_LIMIT_STOP_DEG = 10.0, 2.0
#: the governor judges the configuration this far ahead of the requested motion (s)
LOOKAHEAD_S = 0.15
#: below this fraction of the requested speed the jog stops
MIN_SCALE = 0.05
#: a distance must shrink by more than this over the look-ahead to count as approaching
APPROACH_EPS_M, APPROACH_EPS_DEG = 1e-4, 1e-3
#: damping of the Jacobian pseudo-inverse for Cartesian jogging
DAMPING = 0.02

MODES = ("joint", "base", "tool")
#: key -> (axis 0-5, sign): q w e r t y forward, a s d f g h back (joint 1-6, or X Y Z RX RY RZ)
KEYS = {k: (i, +1) for i, k in enumerate("qwerty")} | {k: (i, -1) for i, k in enumerate("asdfgh")}


class ObstacleMap(Protocol):
    """The watched zone's live obstacle map, as the governor reads it."""

    def clearance_m(self, q_rad: np.ndarray) -> tuple[float, str]:
        """Distance (m) from the arm, tool and held part at ``q_rad`` to the nearest
        occupied voxel, beyond the zone's padding, and a name for where it is."""
        ...


@dataclass
class Verdict:
    """What the governor let through and why."""

    scale: float  # 0..1 of the requested speed
    reason: str  # "" when not held back
    clearance_m: float  # the nearest fixture, beyond its required clearance
    nearest: str
    singularity: str


def requested_qd(
    kinematics: ArmKinematics, q_rad: np.ndarray, mode: str, axis: int, sign: int, speed: float
) -> np.ndarray:
    """Joint speeds (rad/s) for jogging ``axis`` by ``sign`` at ``speed`` (fraction) in
    ``mode``: joints directly; base and tool as a TCP twist through a damped inverse of
    the TCP Jacobian (the base frame is the controller's: the cell's mount turns it)."""
    v = axis_velocity(mode, axis, sign, speed)
    return v if mode == "joint" else twist_qd(kinematics, q_rad, mode, v)


def axis_velocity(mode: str, axis: int, sign: int, speed: float) -> np.ndarray:
    """The velocity of jogging ``axis`` by ``sign`` at ``speed`` (fraction of full jog
    speed): six joint speeds (rad/s) in ``joint`` mode, else a twist (m/s, rad/s)."""
    v = np.zeros(6)
    if mode == "joint":
        v[axis] = sign * math.radians(JOINT_SPEED_DEG_S) * speed
    else:
        full = LINEAR_SPEED_MPS if axis < 3 else math.radians(ANGULAR_SPEED_DEG_S)
        v[axis] = sign * speed * full
    return v


def twist_qd(
    kinematics: ArmKinematics, q_rad: np.ndarray, frame: str, twist: np.ndarray
) -> np.ndarray:
    """Joint speeds (rad/s) giving the TCP ``twist`` (m/s, rad/s) expressed in ``frame``
    (``base``: the controller's base frame, which the cell's mount turns; ``tool``: the
    TCP frame), through a damped inverse of the TCP Jacobian."""
    twist = np.asarray(twist, float)
    R = (
        kinematics.T_world_base[:3, :3]
        if frame == "base"
        else kinematics.T_world_tcp(q_rad)[:3, :3]
    )
    twist_world = np.concatenate([R @ twist[:3], R @ twist[3:]])
    J = kinematics.jacobian_tcp(q_rad)
    return np.asarray(J.T @ np.linalg.solve(J @ J.T + DAMPING**2 * np.eye(6), twist_world))


def _ramp(value: float, slow: float, stop: float) -> float:
    return float(np.clip((value - stop) / (slow - stop), 0.0, 1.0))


class Governor:
    """Scales a requested joint velocity near singularities and obstacles."""

    def __init__(
        self,
        kinematics: ArmKinematics,
        collision: CollisionModel,
        obstacles: ObstacleMap | None = None,
    ) -> None:
        self.kinematics, self.collision, self.obstacles = kinematics, collision, obstacles
        self._fixture_pairs: list[int] | None = None

    def judge(self, q_rad: np.ndarray, qd_rad_s: np.ndarray) -> Verdict:
        q = np.asarray(q_rad, float)
        ahead = q + np.asarray(qd_rad_s, float) * LOOKAHEAD_S
        now, then = (
            self.kinematics.singularity_distance(q),
            self.kinematics.singularity_distance(ahead),
        )
        scale, reason = 1.0, ""
        checks = (
            (
                "wrist singularity",
                now.wrist_deg,
                then.wrist_deg,
                WRIST_SLOW_DEG,
                WRIST_STOP_DEG,
                "deg",
            ),
            (
                "elbow singularity",
                now.elbow_deg,
                then.elbow_deg,
                ELBOW_SLOW_DEG,
                ELBOW_STOP_DEG,
                "deg",
            ),
            (
                "shoulder singularity",
                now.shoulder_m,
                then.shoulder_m,
                SHOULDER_SLOW_M,
                SHOULDER_STOP_M,
                "m",
            ),
        )
        for name, d_now, d_then, slow, stop, unit in checks:
            if d_then < d_now - (
                APPROACH_EPS_DEG if unit == "deg" else APPROACH_EPS_M
            ):  # getting closer
                s = _ramp(d_then, slow, stop)
                if s < scale:
                    scale = s
                    reason = (
                        f"{name} {d_then:.1f} {unit}"
                        if unit == "deg"
                        else f"{name} {d_then * 1000:.0f} mm"
                    )
        m_now, m_then = self._fixture_margins(q), self._fixture_margins(ahead)
        closing = np.flatnonzero(m_then < m_now - APPROACH_EPS_M)  # pair by pair
        for k in closing:
            s = _ramp(m_then[k], CLEARANCE_SLOW_M, CLEARANCE_STOP_M)
            if s < scale:
                scale, reason = s, f"{self._pair_name(int(k))} {m_then[k] * 1000:.0f} mm"
        for name, d_now, d_then, slow, stop in self._limit_checks(q, ahead):
            if d_then < d_now - APPROACH_EPS_DEG:
                s = _ramp(d_then, slow, stop)
                if s < scale:
                    scale, reason = s, f"{name} {d_then:.1f} deg"
        if self.obstacles is not None:
            (o_now, _), (o_then, where) = (
                self.obstacles.clearance_m(q),
                self.obstacles.clearance_m(ahead),
            )
            if o_then < o_now - APPROACH_EPS_M:
                s = _ramp(o_then, CLEARANCE_SLOW_M, CLEARANCE_STOP_M)
                if s < scale:
                    scale, reason = s, f"watched zone: {where} {o_then * 1000:.0f} mm"
        nearest = int(np.argmin(m_now)) if len(m_now) else None
        singularity = f"wrist {now.wrist_deg:.1f} deg, elbow {now.elbow_deg:.1f} deg, shoulder {now.shoulder_m * 1000:.0f} mm"
        if scale < MIN_SCALE:
            scale = 0.0  # the ramp only approaches zero: stop outright
        if nearest is None:
            return Verdict(scale, reason, math.inf, "no fixture", singularity)
        return Verdict(scale, reason, float(m_now[nearest]), self._pair_name(nearest), singularity)

    def _limit_checks(
        self, q: np.ndarray, ahead: np.ndarray
    ) -> list[tuple[str, float, float, float, float]]:
        """Per joint: (name, deg to its nearer range end now, and at the look-ahead, slow,
        stop)."""
        k = self.kinematics
        now = np.degrees(np.minimum(q - k.q_min_rad, k.q_max_rad - q))
        then = np.degrees(np.minimum(ahead - k.q_min_rad, k.q_max_rad - ahead))
        return [
            (
                f"joint {i + 1} limit",
                float(now[i]),
                float(then[i]),
                JOINT_LIMIT_SLOW_DEG,
                JOINT_LIMIT_STOP_DEG,
            )
            for i in range(6)
        ]

    def _fixture_margins(self, q_rad: np.ndarray) -> np.ndarray:
        """Per pair of the arm or tool with a fixture: distance beyond its required
        clearance (m)."""
        if self._fixture_pairs is None:
            self._labels = self.collision.pair_labels
            self._fixture_pairs = [
                k for k, (a, b) in enumerate(self._labels) if BodyKind.FIXTURE in (a.kind, b.kind)
            ]
        if not self._fixture_pairs:
            return np.empty(0)
        distances, required = self.collision.pair_distances(q_rad)
        return np.asarray(distances[self._fixture_pairs] - required[self._fixture_pairs])

    def _pair_name(self, k: int) -> str:
        assert self._fixture_pairs is not None  # named after the margins were measured
        a, b = self._labels[self._fixture_pairs[k]]
        return f"{a} to {b}"


class DeadMan:
    """Which jog key is held, judged from key events and their auto-repeat."""

    def __init__(self) -> None:
        self.key: str | None = None
        self.last_s = 0.0
        self.repeats = 0

    def press(self, key: str, now_s: float) -> None:
        if key != self.key or now_s - self.last_s > self._timeout():
            self.key, self.repeats = key, 0
        else:
            self.repeats += 1
        self.last_s = now_s

    def _timeout(self) -> float:
        return DEADMAN_FIRST_S if self.repeats == 0 else DEADMAN_S

    def held(self, now_s: float) -> str | None:
        """The key held at ``now_s``, None once its repeats stopped coming."""
        if self.key is not None and now_s - self.last_s > self._timeout():
            self.key = None
        return self.key
