"""Motion generators of the virtual controller: what movej, movel, servoj, speedj and stopj do.

Every generator advances the controller's *commanded* joint state (``target_q``,
``target_qd``) by one period: ``advance(q_rad, qd_rad_s, dt_s) -> (q, qd, done)``. The
physics then tracks the commanded positions. Profiles follow UR's description:

- ``movej``: one trapezoidal speed profile on the joint that moves farthest, the other
  joints scaled so that all start and stop together (speed rad/s, acceleration rad/s^2).
- ``movel``: a trapezoidal profile along the straight TCP line (speed m/s, acceleration
  m/s^2); orientation is interpolated by the same fraction; every period is solved with
  IK seeded by the previous joint angles.
- paths with blend radius ``r``: segment k+1 starts while segment k decelerates, from
  the moment segment k is within ``r`` of its waypoint (at most its deceleration time),
  so the two profiles overlap and the arm passes the waypoint without stopping.
- ``servoj``: the commanded position follows the latest target with velocity
  feed-forward plus a first-order correction of time constant
  ``lookahead_time * 100 / gain`` (s) -- a model of UR's filter, not its exact law.
- ``speedj`` / ``speedl``: the joint / TCP velocity ramps to the target at ``a``.
- ``stopj`` / ``stopl``: every joint decelerates so that all stop together at ``a``.

Joint speeds are clipped to the robot's limits in every generator.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cellrunner.twin.kinematics import (
    Kinematics,
    matrix_to_rotvec,
    pose_to_matrix,
    rotvec_to_matrix,
)


class MotionError(Exception):
    """A motion cannot continue (e.g. no IK solution along a movel line)."""


@dataclass(frozen=True)
class Trapezoid:
    """A rest-to-rest trapezoidal (or triangular) profile over ``distance`` units."""

    distance: float
    v_max: float
    a_max: float

    @property
    def t_acc(self) -> float:
        if self.distance <= 0:
            return 0.0
        if self.distance >= self.v_max**2 / self.a_max:
            return self.v_max / self.a_max
        return math.sqrt(self.distance / self.a_max)

    @property
    def v_peak(self) -> float:
        return self.a_max * self.t_acc

    @property
    def duration(self) -> float:
        if self.distance <= 0:
            return 0.0
        ta, vp = self.t_acc, self.v_peak
        return 2 * ta + max(0.0, self.distance - vp * ta) / vp

    def position(self, t: float) -> float:
        """Distance covered at time ``t`` (s) after the start."""
        if self.distance <= 0 or t <= 0:
            return 0.0
        T, ta, vp = self.duration, self.t_acc, self.v_peak
        if t >= T:
            return self.distance
        if t < ta:
            return 0.5 * self.a_max * t * t
        if t <= T - ta:
            return 0.5 * vp * ta + vp * (t - ta)
        r = T - t
        return self.distance - 0.5 * self.a_max * r * r

    def time_at(self, s: float) -> float:
        """Time at which ``s`` units have been covered (inverse of :meth:`position`)."""
        if s <= 0 or self.distance <= 0:
            return 0.0
        T, ta, vp = self.duration, self.t_acc, self.v_peak
        s_acc = 0.5 * vp * ta
        if s >= self.distance:
            return T
        if s < s_acc:
            return math.sqrt(2 * s / self.a_max)
        if s <= self.distance - s_acc:
            return ta + (s - s_acc) / vp
        return T - math.sqrt(2 * (self.distance - s) / self.a_max)


def _clip_speed(qd: np.ndarray, qd_max: np.ndarray) -> np.ndarray:
    """Scale ``qd`` down uniformly so that no joint exceeds its limit (keeps direction)."""
    ratio = float(np.max(np.abs(qd) / qd_max))
    return qd / ratio if ratio > 1.0 else qd


@dataclass
class _Segment:
    start_s: float
    profile: Trapezoid


def _schedule(profiles: list[Trapezoid], overlaps: list[float]) -> list[_Segment]:
    """Start times of consecutive segments, each overlapping the previous by ``overlaps``."""
    segments: list[_Segment] = []
    t = 0.0
    for k, profile in enumerate(profiles):
        if k > 0:
            previous = segments[-1]
            t = previous.start_s + previous.profile.duration - overlaps[k - 1]
        segments.append(_Segment(t, profile))
    return segments


def _overlap(prev: Trapezoid, nxt: Trapezoid, blend_distance: float) -> float:
    """How long segment ``nxt`` starts before ``prev`` ends for a blend of that distance."""
    if blend_distance <= 0 or prev.distance <= 0 or nxt.distance <= 0:
        return 0.0
    t_within = prev.duration - prev.time_at(prev.distance - blend_distance)
    return max(0.0, min(prev.t_acc, nxt.t_acc, t_within))


@dataclass
class _Scheduled:
    """A path of overlapping trapezoid segments through ``waypoints``
    ``(target, speed, accel, blend_m)``, and its timing."""

    q_start: np.ndarray
    waypoints: list[tuple[np.ndarray, float, float, float]]
    kinematics: Kinematics
    qd_max: np.ndarray
    speed_scale: float = 1.0
    t_s: float = 0.0
    _segments: list[_Segment] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        last = self._segments[-1]
        return last.start_s + last.profile.duration if self._segments else 0.0

    @property
    def segment_index(self) -> int:
        """Index of the latest segment that has started (for async progress)."""
        return (
            max(i for i, s in enumerate(self._segments) if s.start_s <= self.t_s)
            if self._segments
            else 0
        )


@dataclass
class JointPath(_Scheduled):
    """movej through joint waypoints ``(q_rad, speed, accel, blend_m)``, synchronized joints."""

    _deltas: list[np.ndarray] = field(default_factory=list)

    def __post_init__(self) -> None:
        points = [np.asarray(self.q_start, float)] + [
            np.asarray(w[0], float) for w in self.waypoints
        ]
        profiles, blends_rad = [], []
        for k, (_q, v, a, r) in enumerate(self.waypoints):
            delta = points[k + 1] - points[k]
            self._deltas.append(delta)
            distance = float(np.max(np.abs(delta)))
            # every joint moves at |delta_j| / distance of the leading joint's speed
            v_eff = v * self.speed_scale
            moving = np.abs(delta) > 1e-12
            if distance > 0 and np.any(moving):
                v_eff = min(
                    v_eff, float(np.min(self.qd_max[moving] * distance / np.abs(delta[moving])))
                )
            profiles.append(
                Trapezoid(distance, max(v_eff, 1e-9), max(a * self.speed_scale**2, 1e-9))
            )
            tcp_m = float(
                np.linalg.norm(
                    self.kinematics.tcp(points[k + 1])[:3, 3]
                    - self.kinematics.tcp(points[k])[:3, 3]
                )
            )
            blends_rad.append(r * distance / tcp_m if tcp_m > 1e-9 and r > 0 else 0.0)
        overlaps = [
            _overlap(profiles[k], profiles[k + 1], blends_rad[k]) for k in range(len(profiles) - 1)
        ]
        self._segments = _schedule(profiles, overlaps)

    def _q_at(self, t: float) -> np.ndarray:
        q = np.array(self.q_start, dtype=float)
        for seg, delta in zip(self._segments, self._deltas, strict=True):
            if seg.profile.distance > 0:
                q = q + delta * (seg.profile.position(t - seg.start_s) / seg.profile.distance)
        return q

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        self.t_s += dt
        q_new = self._q_at(self.t_s)
        return q_new, (q_new - q) / dt, self.t_s >= self.duration_s


@dataclass
class LinearPath(_Scheduled):
    """movel through TCP poses ``(pose, speed, accel, blend_m)``, straight lines in base."""

    _dp: list[np.ndarray] = field(default_factory=list)
    _dw: list[np.ndarray] = field(default_factory=list)

    def __post_init__(self) -> None:
        T0 = self.kinematics.tcp(np.asarray(self.q_start, float))
        self._p0, self._R0 = T0[:3, 3].copy(), T0[:3, :3].copy()
        p_prev, R_prev = self._p0, self._R0
        profiles, blends = [], []
        for pose, v, a, r in self.waypoints:
            T = pose_to_matrix(pose)
            dp, dw = T[:3, 3] - p_prev, matrix_to_rotvec(R_prev.T @ T[:3, :3])
            self._dp.append(dp)
            self._dw.append(dw)
            lin, ang = float(np.linalg.norm(dp)), float(np.linalg.norm(dw))
            v_eff, a_eff = max(v * self.speed_scale, 1e-9), max(a * self.speed_scale**2, 1e-9)
            # the orientation change uses the same numbers as rad/s and rad/s^2; the
            # slower of the two profiles sets the pace of the segment
            by_position, by_rotation = Trapezoid(lin, v_eff, a_eff), Trapezoid(ang, v_eff, a_eff)
            profiles.append(
                by_position if by_position.duration >= by_rotation.duration else by_rotation
            )
            blends.append(r if by_position.duration >= by_rotation.duration else 0.0)
            p_prev, R_prev = T[:3, 3], T[:3, :3]
        overlaps = [
            _overlap(profiles[k], profiles[k + 1], blends[k]) for k in range(len(profiles) - 1)
        ]
        self._segments = _schedule(profiles, overlaps)

    def _pose_at(self, t: float) -> np.ndarray:
        p, R = self._p0.copy(), self._R0.copy()
        for seg, dp, dw in zip(self._segments, self._dp, self._dw, strict=True):
            if seg.profile.distance > 0:
                f = seg.profile.position(t - seg.start_s) / seg.profile.distance
                p = p + dp * f
                R = R @ rotvec_to_matrix(dw * f)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, p
        return T

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        self.t_s += dt
        q_new = self.kinematics.inverse(self._pose_at(self.t_s), q, iterations=20)
        if q_new is None:
            raise MotionError("movel: no inverse kinematics solution along the line")
        qd_new = (q_new - q) / dt
        over = np.abs(qd_new) / self.qd_max
        if np.any(over > 1.5):
            j = int(np.argmax(over))
            raise MotionError(
                f"movel: joint {j + 1} would need {abs(qd_new[j]):.2f} rad/s at t={self.t_s:.3f} s "
                f"(limit {self.qd_max[j]:.2f}); the line passes near a singularity (q={np.round(q, 4).tolist()})"
            )
        return q_new, qd_new, self.t_s >= self.duration_s


@dataclass
class Stop:
    """stopj / stopl: decelerate all joints together at ``decel`` (rad/s^2 of the fastest)."""

    decel: float

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        peak = float(np.max(np.abs(qd)))
        if peak <= self.decel * dt or peak == 0.0:
            return q, np.zeros(6), True
        qd_new = qd * (1.0 - self.decel * dt / peak)
        return q + 0.5 * (qd + qd_new) * dt, qd_new, False


@dataclass
class Servo:
    """servoj: follow the latest target (see the module docstring for the model)."""

    qd_max: np.ndarray
    accel_max: float
    target: np.ndarray | None = None
    feed_forward: np.ndarray = field(default_factory=lambda: np.zeros(6))
    period_s: float = 0.002
    lookahead_s: float = 0.1
    gain: float = 300.0
    _age_s: float = 0.0

    def set_target(
        self, q_rad: np.ndarray, period_s: float, lookahead_s: float, gain: float
    ) -> None:
        q_rad = np.asarray(q_rad, dtype=float)
        period_s = max(period_s, 1e-3)
        if self.target is not None and np.array_equal(q_rad, self.target):
            return  # the same command seen again in a later period: nothing new
        if self.target is not None and self._age_s <= 3 * period_s:
            self.feed_forward = (q_rad - self.target) / period_s
        else:
            self.feed_forward = np.zeros(6)
        self.target, self.period_s, self._age_s = q_rad, period_s, 0.0
        self.lookahead_s, self.gain = lookahead_s, gain

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        if self.target is None:
            return q, np.zeros(6), False
        self._age_s += dt
        if self._age_s > 2 * self.period_s:  # the stream paused: stop feeding forward
            self.feed_forward = np.zeros(6)
        tau = max(dt, self.lookahead_s * 100.0 / max(self.gain, 1.0))
        qd_new = self.feed_forward + (self.target - q) / tau
        qd_new = _clip_speed(qd_new, self.qd_max)
        dqd = qd_new - qd
        peak = float(np.max(np.abs(dqd)))
        if peak > self.accel_max * dt:
            qd_new = qd + dqd * (self.accel_max * dt / peak)
        return q + qd_new * dt, qd_new, False


@dataclass
class SpeedJ:
    """speedj: ramp joint speeds to ``qd_target`` at ``accel`` and hold them."""

    qd_target: np.ndarray
    accel: float
    qd_max: np.ndarray

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        target = _clip_speed(np.asarray(self.qd_target, float), self.qd_max)
        dqd = target - qd
        peak = float(np.max(np.abs(dqd)))
        if peak > self.accel * dt:
            dqd = dqd * (self.accel * dt / peak)
        qd_new = qd + dqd
        return q + 0.5 * (qd + qd_new) * dt, qd_new, False


@dataclass
class SpeedL:
    """speedl: ramp the TCP twist (m/s, rad/s in base) to ``xd_target`` at ``accel``."""

    xd_target: np.ndarray
    accel: float
    kinematics: Kinematics
    qd_max: np.ndarray
    xd: np.ndarray = field(default_factory=lambda: np.zeros(6))

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        dxd = np.asarray(self.xd_target, float) - self.xd
        peak = float(np.max(np.abs(dxd)))
        if peak > self.accel * dt:
            dxd = dxd * (self.accel * dt / peak)
        self.xd = self.xd + dxd
        J = self.kinematics.jacobian(q)
        qd_new = np.linalg.solve(J.T @ J + 1e-6 * np.eye(6), J.T @ self.xd)
        qd_new = _clip_speed(qd_new, self.qd_max)
        return q + qd_new * dt, qd_new, False


@dataclass
class UntilContact:
    """moveUntilContact: speedl until ``in_contact()`` reports tool contact, then stop."""

    speed: SpeedL
    in_contact: Callable[[], bool]
    decel: float = 3.0
    stop: Stop | None = None

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        if self.stop is None and self.in_contact():
            self.stop = Stop(self.decel)
        if self.stop is not None:
            return self.stop.advance(q, qd, dt)
        return self.speed.advance(q, qd, dt)
