"""A model of how long a PolyScope program takes: ``movej``/``movel`` with blend radii.

Used by ``bench_cycle.py`` to time the job a UR integrator would write by hand, at the
same limits cellrunner plans with. Everything is measured the way cellrunner's verifier
measures its own trajectories: positions sampled at the controller rate, speeds and
accelerations by finite differences, TCP speed by forward kinematics.

**movej** (URScript ``movej(q, a, v)``): every joint follows the same normalised
trapezoidal speed profile (a triangle when the move is too short to cruise), so all
joints start and stop together; the duration is that of the slowest joint,
``max_i trapezoid(|dq_i|, v_i, a_i)`` with ``v_i``/``a_i`` the cell's joint speed and
acceleration (x margin, as cellrunner uses them). UR does not cap the TCP speed of a
``movej``; the cell's TCP cap is a safety limit, so where the move would exceed it the
programmer slows the move down (the whole profile is stretched in time by the excess, as
the speed slider does).

**movel** (``movel(pose, a, v)``): the TCP follows the line with a trapezoidal speed
profile in distance. ``v`` is the step's TCP speed (the cell's cap x margin unless the step
sets one), lowered to what the joint speed limits allow along the line; ``a`` is the
largest TCP acceleration (found by bisection) that keeps every joint's acceleration,
``q'(x) x'' + q''(x) x'^2``, within the cell's limit at every sample: the fastest ``movel``
a programmer could set without the arm exceeding the cell's joint limits.

**Blends** (the waypoint's blend radius ``r``, UR's "blend with radius"): the blend starts
when the TCP enters the sphere of radius ``r`` around the waypoint and ends when it leaves
it on the next move, during which the two moves are superposed (the next starts while the
previous finishes). The time saved at that waypoint is the overlap
``min(T_in, T_out)``: ``T_in`` the time the first move spends inside the sphere at its
end, ``T_out`` the time the next spends inside it at its start. Like PolyScope, a radius
is at most half of either neighbouring move's TCP travel (overlapping blends are refused).
The model is generous to PolyScope: the summed accelerations during a blend are not
charged against the joint limits.

**Radii a good integrator uses** (:func:`blend_radius`): none where something happens at
the waypoint (grip, release, IO, a wait, weighing the part after a lift) or at the end of
the program; at a via point between two joint moves the largest radius PolyScope accepts
(half the shorter neighbour, up to ``VIA_RADIUS_MAX_M``); where a joint move meets a
straight approach, descend, lift or retreat, at most ``LINEAR_BLEND_FRACTION`` of the
straight move (so the part end of it stays straight) and ``APPROACH_RADIUS_MAX_M``.
cellrunner blends with the same allowances (``planning.task_plan.LINEAR_BLEND_FRACTION``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the largest blend radius at a via point between two joint moves (m)
VIA_RADIUS_MAX_M = 0.20
#: where a joint move meets a straight move: at most this share of the straight move...
LINEAR_BLEND_FRACTION = 0.4
#: ... and at most this radius (m)
APPROACH_RADIUS_MAX_M = 0.05


@dataclass(frozen=True)
class Move:
    """One ``movej`` or ``movel`` of the program, timed from rest to rest: its duration (s)
    and the TCP positions (N x 3, world, m) sampled at the controller rate."""

    kind: str  # movej | movel
    duration_s: float
    p_m: np.ndarray

    @property
    def travel_m(self) -> float:
        """Chord from start to end of the TCP (m), what PolyScope's blend limit compares."""
        return float(np.linalg.norm(self.p_m[-1] - self.p_m[0]))

    def time_inside_end_s(self, radius_m: float, rate_hz: float) -> float:
        """How long the TCP stays within ``radius_m`` of the end point at the end (s)."""
        d = np.linalg.norm(self.p_m - self.p_m[-1], axis=1)
        outside = np.nonzero(d >= radius_m)[0]
        return self.duration_s if len(outside) == 0 else (len(d) - 1 - outside[-1]) / rate_hz

    def time_inside_start_s(self, radius_m: float, rate_hz: float) -> float:
        """How long the TCP stays within ``radius_m`` of the start point at the start (s)."""
        d = np.linalg.norm(self.p_m - self.p_m[0], axis=1)
        outside = np.nonzero(d >= radius_m)[0]
        return self.duration_s if len(outside) == 0 else outside[0] / rate_hz


def trapezoid_s(distance: float, speed: float, accel: float) -> float:
    """Duration (s) of a rest-to-rest move of ``distance`` with a trapezoidal speed profile
    (cruise at ``speed``), or a triangular one when too short to reach it."""
    distance = abs(float(distance))
    if distance == 0.0:
        return 0.0
    if distance >= speed * speed / accel:
        return distance / speed + speed / accel
    return 2.0 * math.sqrt(distance / accel)


def trapezoid_fraction(t_s: np.ndarray, duration_s: float, accel_s: float) -> np.ndarray:
    """Fraction of the move done (0..1) at times ``t_s`` for a symmetric trapezoid of
    ``duration_s`` with ``accel_s`` seconds of acceleration (= duration/2 for a triangle)."""
    t = np.clip(np.asarray(t_s, float), 0.0, duration_s)
    ta, T = accel_s, duration_s
    v = 1.0 / (T - ta)  # cruise speed in fraction per second
    a = v / ta
    return np.where(
        t < ta,
        0.5 * a * t * t,
        np.where(t <= T - ta, 0.5 * a * ta * ta + v * (t - ta), 1.0 - 0.5 * a * (T - t) ** 2),
    )


def _profile(distance: float, speed: float, accel: float) -> tuple[float, float]:
    """(duration, acceleration time) of the trapezoid (s)."""
    duration = trapezoid_s(distance, speed, accel)
    accel_s = min(speed / accel, duration / 2)
    return duration, accel_s


def _samples(duration_s: float, rate_hz: float) -> np.ndarray:
    n = max(1, math.ceil(duration_s * rate_hz - 1e-9))
    return np.minimum(np.arange(n + 1) / rate_hz, duration_s)


def movej(kin, q_from_rad: np.ndarray, q_to_rad: np.ndarray, limits, rate_hz: float) -> Move:
    """A ``movej`` at the cell's joint limits (module docstring)."""
    from cellrunner.planning.timing import sample_measures

    q0, q1 = np.asarray(q_from_rad, float), np.asarray(q_to_rad, float)
    dq = q1 - q0
    times = [
        _profile(abs(d), v, a)
        for d, v, a in zip(dq, limits.joint_speed_rad_s, limits.joint_accel_rad_s2, strict=True)
    ]
    duration, accel_s = max(times)
    if duration == 0.0:
        return Move("movej", 0.0, kin.p_world_tcp_many(q0[None, :]))
    stretch = 1.0
    for _ in range(6):
        T, ta = duration * stretch, accel_s * stretch
        q = q0 + trapezoid_fraction(_samples(T, rate_hz), T, ta)[:, None] * dq
        _, _, tcp = sample_measures(kin, q, rate_hz)
        excess = float(tcp.max()) / limits.tcp_speed_mps
        if excess <= 1.0:
            return Move("movej", T, kin.p_world_tcp_many(q))
        stretch *= excess * 1.001
    return Move("movej", T, kin.p_world_tcp_many(q))


def movel(kin, q_line_rad: np.ndarray, limits, rate_hz: float) -> Move:
    """A ``movel`` along the joint samples ``q_line_rad`` (N x 6, IK of the straight TCP
    line, as planned) at the fastest speed and acceleration within the cell's limits."""
    from cellrunner.planning.timing import sample_measures

    q_line = np.asarray(q_line_rad, float)
    p_line = kin.p_world_tcp_many(q_line)
    x = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p_line, axis=0), axis=1))])
    length = float(x[-1])
    if length < 1e-9:
        return Move("movel", 0.0, p_line[:1])
    keep = np.concatenate([[True], np.diff(x) > 1e-9])
    from scipy.interpolate import CubicSpline

    q_of_x = CubicSpline(x[keep], q_line[keep], axis=0)  # smooth: no kinks at the IK samples
    dq_dx = np.abs(q_of_x(x, 1))
    speed = min(
        limits.tcp_speed_mps, float(np.min(limits.joint_speed_rad_s / np.maximum(dq_dx, 1e-12)))
    )

    def sampled(accel: float, v: float) -> np.ndarray:
        T, ta = _profile(length, v, accel)
        u = trapezoid_fraction(_samples(T, rate_hz), T, ta) * length
        return q_of_x(u)

    def within(accel: float, v: float) -> bool:
        vel, acc, tcp = sample_measures(kin, sampled(accel, v), rate_hz)
        return bool(
            (np.abs(vel) <= limits.joint_speed_rad_s * 1.000001).all()
            and (np.abs(acc) <= limits.joint_accel_rad_s2 * 1.000001).all()
            and tcp.max() <= limits.tcp_speed_mps * 1.000001
        )

    for _ in range(20):  # the speed from the joint limits holds on the samples' chords
        lo, hi = 1e-3, 100.0
        if within(lo, speed):
            break
        speed *= 0.98
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if within(mid, speed) else (lo, mid)
    T, _ = _profile(length, speed, lo)
    return Move("movel", T, kin.p_world_tcp_many(sampled(lo, speed)))


def blend_radius(before: Move, after: Move, *, stop: bool, via: bool) -> float:
    """The radius a good integrator sets at the waypoint between ``before`` and ``after``
    (module docstring): 0 when the arm must stop there (``stop``); ``via``: a via point
    between joint moves."""
    if stop or before.duration_s == 0.0 or after.duration_s == 0.0:
        return 0.0
    limit = 0.5 * min(before.travel_m, after.travel_m)
    if via or (before.kind == "movej" and after.kind == "movej"):
        return min(limit, VIA_RADIUS_MAX_M)
    straight = [m.travel_m for m in (before, after) if m.kind == "movel"]
    return min(limit, LINEAR_BLEND_FRACTION * min(straight), APPROACH_RADIUS_MAX_M)


def program_time_s(
    moves: list[Move], radii_m: list[float], rate_hz: float
) -> tuple[float, list[float]]:
    """Duration (s) of ``moves`` run one after the other, blended at the waypoint after
    move i with radius ``radii_m[i]`` (0 = stop), and the time saved at each waypoint."""
    saved = []
    for i, (move, r) in enumerate(zip(moves[:-1], radii_m, strict=True)):
        if r <= 0.0:
            saved.append(0.0)
            continue
        nxt = moves[i + 1]
        saved.append(min(move.time_inside_end_s(r, rate_hz), nxt.time_inside_start_s(r, rate_hz)))
    return sum(m.duration_s for m in moves) - sum(saved), saved
