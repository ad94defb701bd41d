"""The final independent check of a sampled trajectory, and the only caller of ``approve``.

It trusts nothing the planner computed: given the samples that would be streamed, it
re-measures everything from them.

- time grid: ``t_s[k] = k / rate_hz`` exactly, at the controller rate of the arm;
- joint position limits at every sample;
- continuity: the first sample equals the previous step's last one (or the start state);
- joint speeds and accelerations by finite differences (including the junction with the
  previous step, and rest before/after where the motion starts/ends at rest), within the
  limits (already x margin) plus ``RELATIVE_TOLERANCE``;
- TCP speed by forward kinematics of consecutive samples, within the cap;
- straightness for linear steps: every sample's TCP within ``STRAIGHTNESS_M`` of the line;
- collisions between consecutive samples, proven by :meth:`CollisionModel.check_path`.

Any failure raises :class:`InfeasibleError` naming the step and the violation with numbers.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.robots import JOINT_NAMES
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory, approve
from cellrunner.planning.cartesian import distance_to_segment_m
from cellrunner.planning.collision import CollisionModel
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.timing import MotionLimits, sample_measures

RELATIVE_TOLERANCE = 1e-6
STRAIGHTNESS_M = 0.001
CONTINUITY_RAD = 1e-9


class _Fail(Protocol):
    """Builds the refusal of the step being verified (:func:`verify_trajectory`)."""

    def __call__(
        self,
        message: str,
        kind: FailureKind = FailureKind.TRAJECTORY,
        blockers: tuple[Blocker, ...] = (),
    ) -> InfeasibleError: ...


def verify_trajectory(
    trajectory: Trajectory,
    *,
    step_index: int,
    step_name: str,
    kinematics: ArmKinematics,
    limits: MotionLimits,
    collision: CollisionModel,
    previous_q_rad: np.ndarray | None = None,
    previous_moving: bool = False,
    ends_at_rest: bool = True,
    line_m: tuple[np.ndarray, np.ndarray] | None = None,
) -> ApprovedTrajectory:
    """Check ``trajectory`` (module docstring) and return it approved, or raise.

    ``previous_q_rad``: the last two samples of the previous step (2 x 6) when it runs
    straight into this one (``previous_moving``), else the state this step starts from
    (6,) at rest. ``line_m``: (start, goal) TCP positions in the world for linear steps.
    """
    where = f"step {step_index} {step_name}"

    def fail(
        message: str,
        kind: FailureKind = FailureKind.TRAJECTORY,
        blockers: tuple[Blocker, ...] = (),
    ) -> InfeasibleError:
        return InfeasibleError(Failure(kind, message, (), blockers, "", step_index, where))

    q = np.asarray(trajectory.q_rad, float)
    rate = float(trajectory.rate_hz)
    _check_grid(trajectory, q, rate, kinematics, fail)
    _check_joint_range(q, kinematics, fail)
    head = _head(q, previous_q_rad, previous_moving, fail)
    padded = q if head is None else np.vstack([head, q])
    p_tcp = kinematics.p_world_tcp_many(padded)  # for the TCP speed and the straightness
    _check_rates(kinematics, limits, padded, rate, head is None, ends_at_rest, p_tcp, fail)
    if line_m is not None:
        _check_straight(p_tcp if head is None else p_tcp[1:], line_m, fail)
    _check_collisions(collision, q, rate, fail)
    return approve(trajectory, step_index, step_name)


def _check_grid(
    trajectory: Trajectory, q: np.ndarray, rate: float, kinematics: ArmKinematics, fail: _Fail
) -> None:
    """Samples there are, at the controller's rate, on its time grid t = k / rate."""
    if len(q) == 0:
        raise fail("empty trajectory")
    if abs(rate - kinematics.spec.rate_hz) > 1e-9:
        raise fail(
            f"sampled at {rate:g} Hz, the {kinematics.spec.name} controller runs at {kinematics.spec.rate_hz:g} Hz"
        )
    grid = np.arange(len(q)) / rate
    if np.abs(np.asarray(trajectory.t_s) - grid).max() > 1e-9:
        raise fail("samples are not on the controller's time grid t = k / rate")


def _check_joint_range(q: np.ndarray, kinematics: ArmKinematics, fail: _Fail) -> None:
    """Every sample within the joints' ranges."""
    below = q < kinematics.q_min_rad - 1e-12
    above = q > kinematics.q_max_rad + 1e-12
    if below.any() or above.any():
        k, i = np.argwhere(below | above)[0]
        source = "robot.joint_range" if kinematics.spec.joint_range_narrowed else "the controller's"
        raise fail(
            f"joint {i + 1} ({JOINT_NAMES[i]}) at {np.degrees(q[k, i]):.1f} deg is outside "
            f"its range [{np.degrees(kinematics.q_min_rad[i]):.0f}, "
            f"{np.degrees(kinematics.q_max_rad[i]):.0f}] deg ({source}) at sample {k}",
            FailureKind.LIMITS,
        )


def _head(
    q: np.ndarray, previous_q_rad: np.ndarray | None, previous_moving: bool, fail: _Fail
) -> np.ndarray | None:
    """The sample before the first one when the previous motion runs straight into this
    one (None: from rest), after checking that this one starts where that one ended."""
    head = None
    if previous_q_rad is not None:
        prev = np.atleast_2d(np.asarray(previous_q_rad, float))
        jump = float(np.abs(q[0] - prev[-1]).max())
        if jump > CONTINUITY_RAD:
            raise fail(
                f"starts {np.degrees(jump):.4f} deg away from where the previous motion ended"
            )
        if previous_moving and len(prev) >= 2:
            head = prev[-2:-1]
    return head


def _check_rates(
    kinematics: ArmKinematics,
    limits: MotionLimits,
    padded: np.ndarray,
    rate: float,
    rest_before: bool,
    ends_at_rest: bool,
    p_tcp: np.ndarray,
    fail: _Fail,
) -> None:
    """Joint speeds and accelerations and the TCP's speed within the limits."""
    v, a, tcp = sample_measures(
        kinematics,
        padded,
        rate,
        rest_before=rest_before,
        rest_after=ends_at_rest,
        p_world_tcp_m=p_tcp,
    )
    tol = 1 + RELATIVE_TOLERANCE
    for name, values, limit, unit, scale in (
        ("speed", v, limits.joint_speed_rad_s, "deg/s", np.degrees(1.0)),
        ("acceleration", a, limits.joint_accel_rad_s2, "deg/s^2", np.degrees(1.0)),
    ):
        ratio = np.abs(values) / limit
        if ratio.size and ratio.max() > tol:
            k, i = np.unravel_index(int(ratio.argmax()), ratio.shape)
            raise fail(
                f"{JOINT_NAMES[i]} {name} {abs(values[k, i]) * scale:.1f} {unit} exceeds "
                f"the limit {limit[i] * scale:.1f} {unit} (sample {k})",
                FailureKind.LIMITS,
            )
    if len(tcp) and tcp.max() > limits.tcp_speed_mps * tol:
        raise fail(
            f"TCP speed {tcp.max():.3f} m/s exceeds the cap {limits.tcp_speed_mps:.3f} m/s",
            FailureKind.LIMITS,
        )


def _check_straight(p: np.ndarray, line_m: tuple[np.ndarray, np.ndarray], fail: _Fail) -> None:
    """Every sample's TCP (``p``) within ``STRAIGHTNESS_M`` of the line."""
    off = distance_to_segment_m(p, np.asarray(line_m[0]), np.asarray(line_m[1]))
    if off.max() > STRAIGHTNESS_M:
        raise fail(
            f"TCP leaves the straight line by {off.max() * 1000:.2f} mm "
            f"(allowed {STRAIGHTNESS_M * 1000:.1f} mm, sample {int(off.argmax())})"
        )


def _check_collisions(collision: CollisionModel, q: np.ndarray, rate: float, fail: _Fail) -> None:
    """No collision between consecutive samples (proven by the model's path check)."""
    result = collision.check_path(q)
    if not result.ok:
        c = result.clearance
        detail = c.describe() if c else "collision"
        raise fail(
            f"{detail} at t = {(result.s_blocked or 0.0) / rate:.3f} s",
            FailureKind.COLLISION,
            (Blocker(c.b, c.distance_m), Blocker(c.a, c.distance_m)) if c else (),
        )
