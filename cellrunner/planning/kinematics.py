"""Arm kinematics: forward kinematics, Jacobian, singularity distances and inverse kinematics.

Frames (4x4 homogeneous matrices, ``T_parent_child``):

- ``world``: the cell frame; ``T_world_base`` is the robot mount (SPEC section 3).
- ``base``: the controller's base frame, DH frame 0.
- ``flange``: tool0, DH frame 6.
- ``tcp``: the tool centre point, ``T_flange_tcp`` from the cell file.

Joint angles are in radians, ``q_rad`` of shape (6,), in the controller's convention (the
DH angle of joint i is q_i; no offsets). The pinocchio model places joint i at the DH
offsets of link i-1, so the frame of joint i is "DH frame i-1 turned by joint i", the frame
in which the arm's collision parts (:mod:`cellrunner.model.arm_geometry`) are expressed.

Inverse kinematics is closed-form (ur-analytic-ik, up to 8 branches); the branch nearest a
given configuration inside the joint limits is chosen and verified by forward kinematics.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.geometry import invert
from cellrunner.model.robots import JOINT_NAMES, RobotSpec

#: FK residual above which an IK solution is rejected (position m, rotation rad).
IK_TOLERANCE_M = 1e-6
IK_TOLERANCE_RAD = 1e-6
#: how far (rad about the flange Z, m along its Y) a pose is nudged when the solver
#: dropped branches at it; well inside the tolerance FK verifies IK with
IK_NUDGE = 1e-7


@dataclass(frozen=True)
class SingularityDistance:
    """How far a configuration is from each of the three UR singularities.

    - ``wrist_deg``: |q5| away from 0 or 180 deg (wrist 1 and wrist 3 axes parallel).
    - ``elbow_deg``: |q3| away from 0 or 180 deg (arm stretched out or folded).
    - ``shoulder_m``: horizontal distance of the wrist point (DH frame 5 origin) from the
      cylinder of radius d4 around the base axis, where the two shoulder branches merge.
    """

    wrist_deg: float
    elbow_deg: float
    shoulder_m: float

    def violation(self, min_angle_deg: float, min_shoulder_m: float) -> str | None:
        """A message naming the nearest singularity closer than the thresholds, or None."""
        if self.wrist_deg < min_angle_deg:
            return (
                f"wrist singularity (wrist 2 at {self.wrist_deg:.1f} deg from 0/180, "
                f"needs >= {min_angle_deg:.1f} deg)"
            )
        if self.elbow_deg < min_angle_deg:
            return (
                f"elbow singularity (elbow at {self.elbow_deg:.1f} deg from straight/folded, "
                f"needs >= {min_angle_deg:.1f} deg)"
            )
        if self.shoulder_m < min_shoulder_m:
            return (
                f"shoulder singularity (wrist {self.shoulder_m * 1000:.0f} mm from the "
                f"base-axis cylinder, needs >= {min_shoulder_m * 1000:.0f} mm)"
            )
        return None


def _angle_from_line_deg(q: float) -> float:
    """Angle in degrees between q and the nearest multiple of pi."""
    return math.degrees(abs(math.remainder(q, math.pi)))


def dh_link(d: float, a: float, alpha: float) -> pin.SE3:
    """The fixed part of a DH link: translate d along z, a along x, rotate alpha about x."""
    T = np.eye(4)
    ca, sa = math.cos(alpha), math.sin(alpha)
    T[:3, :3] = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    T[:3, 3] = [a, 0, d]
    return pin.SE3(T)


class ArmKinematics:
    """Kinematics of one UR arm mounted at ``T_world_base`` carrying a tool ``T_flange_tcp``."""

    def __init__(self, spec: RobotSpec, T_world_base: np.ndarray, T_flange_tcp: np.ndarray) -> None:
        self.spec = spec
        self.T_world_base = np.array(T_world_base, dtype=float)
        self.T_flange_tcp = np.array(T_flange_tcp, dtype=float)
        self.q_min_rad = np.radians(spec.joint_min_deg)
        self.q_max_rad = np.radians(spec.joint_max_deg)
        self.model = self._build_model()
        self.data = self.model.createData()
        self.flange_frame_id = self.model.getFrameId("flange")
        self.tcp_frame_id = self.model.getFrameId("tcp")
        self._ik = _ik_module(spec.name)

    def _build_model(self) -> pin.Model:
        spec = self.spec
        model = pin.Model()
        model.name = spec.name
        parent = 0
        placement = pin.SE3(self.T_world_base)
        for i, name in enumerate(JOINT_NAMES):
            parent = model.addJoint(parent, pin.JointModelRZ(), placement, name)
            model.appendBodyToJoint(parent, pin.Inertia.Identity(), pin.SE3.Identity())
            placement = dh_link(spec.d_m[i], spec.a_m[i], spec.alpha_rad[i])
        model.lowerPositionLimit = np.radians(spec.joint_min_deg)
        model.upperPositionLimit = np.radians(spec.joint_max_deg)
        model.velocityLimit = np.radians(spec.joint_speed_max_deg_s)
        last = model.nframes - 1
        flange = model.addFrame(
            pin.Frame("flange", parent, last, placement, pin.FrameType.OP_FRAME)
        )
        model.addFrame(
            pin.Frame(
                "tcp",
                parent,
                flange,
                placement * pin.SE3(self.T_flange_tcp),
                pin.FrameType.OP_FRAME,
            )
        )
        return model

    # -- forward kinematics --------------------------------------------------------------

    def T_world_tcp(self, q_rad: np.ndarray) -> np.ndarray:
        """Pose of the TCP in the world at ``q_rad``."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, dtype=float))
        return np.asarray(self.data.oMf[self.tcp_frame_id].homogeneous.copy())

    def p_world_tcp(self, q_rad: np.ndarray) -> np.ndarray:
        """Position of the TCP in the world at ``q_rad`` (m)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, dtype=float))
        return np.asarray(self.data.oMf[self.tcp_frame_id].translation.copy())

    def T_world_flange(self, q_rad: np.ndarray) -> np.ndarray:
        """Pose of the flange (tool0) in the world at ``q_rad``."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, dtype=float))
        return np.asarray(self.data.oMf[self.flange_frame_id].homogeneous.copy())

    def p_world_tcp_many(self, q_rad: np.ndarray) -> np.ndarray:
        """TCP positions in the world (N x 3) for configurations ``q_rad`` (N x 6), computed
        for all N at once (the joint chain as arrays of rotations)."""
        q = np.asarray(q_rad, dtype=float).reshape(-1, 6)
        n = len(q)
        R = np.empty((n, 3, 3))
        R[:] = np.eye(3)
        p = np.zeros((n, 3))
        cos, sin = np.cos(q), np.sin(q)
        # (n, 3, 3) @ (3, 3) as one (3n, 3) product: numpy's broadcast matmul of small
        # matrices loops per sample (4x slower on 1000 samples, measured)
        for j, (R_link, p_link) in enumerate(self._chain):
            p += (R.reshape(-1, 3) @ p_link).reshape(n, 3)
            R = (R.reshape(-1, 3) @ R_link).reshape(n, 3, 3)
            c, s = cos[:, j, None], sin[:, j, None]
            x, y = R[:, :, 0].copy(), R[:, :, 1].copy()
            R[:, :, 0] = c * x + s * y  # R @ Rz(q_j)
            R[:, :, 1] = c * y - s * x
        return np.asarray(p + (R.reshape(-1, 3) @ self._p_joint6_tcp).reshape(n, 3))

    @functools.cached_property
    def _chain(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each joint's placement in its parent (rotation, translation), base to wrist 3."""
        return [
            (
                self.model.jointPlacements[j].rotation.copy(),
                self.model.jointPlacements[j].translation.copy(),
            )
            for j in range(1, 7)
        ]

    @functools.cached_property
    def tcp_lever_arms_m(self) -> np.ndarray:
        """Per joint, a bound on the TCP's distance from that joint's axis (m): the
        lengths of the links after it and of the TCP offset, added. Between two
        configurations the TCP moves at most ``|q_a - q_b| @ tcp_lever_arms_m``."""
        lengths = [float(np.linalg.norm(p)) for _, p in self._chain[1:]]
        lengths.append(float(np.linalg.norm(self._p_joint6_tcp)))
        return np.cumsum(lengths[::-1])[::-1]

    @functools.cached_property
    def _p_joint6_tcp(self) -> np.ndarray:
        return np.asarray(self.model.frames[self.tcp_frame_id].placement.translation.copy())

    def jacobian_tcp(self, q_rad: np.ndarray) -> np.ndarray:
        """6x6 Jacobian of the TCP: rows 0-2 its linear velocity in world axes (m/s per
        rad/s), rows 3-5 its angular velocity in world axes (rad/s per rad/s)."""
        q = np.asarray(q_rad, dtype=float)
        J: np.ndarray = pin.computeFrameJacobian(
            self.model, self.data, q, self.tcp_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        ).copy()
        return J

    def manipulability(self, q_rad: np.ndarray) -> float:
        """Smallest singular value of the TCP position Jacobian (m/rad): the slowest TCP
        speed per unit joint speed in the worst direction."""
        return float(np.linalg.svd(self.jacobian_tcp(q_rad)[:3], compute_uv=False)[-1])

    def singularity_distance(self, q_rad: np.ndarray) -> SingularityDistance:
        """Distances of ``q_rad`` from the wrist, elbow and shoulder singularities."""
        q = np.asarray(q_rad, dtype=float)
        pin.forwardKinematics(self.model, self.data, q)
        T_base_world = invert(self.T_world_base)
        p_world_wrist = self.data.oMi[6].translation  # joint 6 origin = DH frame 5 origin
        p_base_wrist = T_base_world[:3, :3] @ p_world_wrist + T_base_world[:3, 3]
        radial_m = math.hypot(p_base_wrist[0], p_base_wrist[1])
        return SingularityDistance(
            wrist_deg=_angle_from_line_deg(q[4]),
            elbow_deg=_angle_from_line_deg(q[2]),
            shoulder_m=abs(radial_m - abs(self.spec.d_m[3])),
        )

    # -- inverse kinematics --------------------------------------------------------------

    def within_limits(self, q_rad: np.ndarray) -> bool:
        q = np.asarray(q_rad)
        return bool(np.all(q >= self.q_min_rad - 1e-9) and np.all(q <= self.q_max_rad + 1e-9))

    def ik_all(self, T_world_tcp: np.ndarray, q_near_rad: np.ndarray) -> list[np.ndarray]:
        """Every verified IK branch for ``T_world_tcp``, each wrapped (by multiples of 2 pi
        per joint) nearest to ``q_near_rad`` within the joint limits, sorted by distance to
        ``q_near_rad``. Empty when the pose is unreachable."""
        T_base_flange = (
            invert(self.T_world_base) @ np.asarray(T_world_tcp) @ invert(self.T_flange_tcp)
        )
        q_near = np.asarray(q_near_rad, dtype=float)
        found: list[np.ndarray] = []
        for raw in self._solve(T_base_flange):
            q = self._wrap_near(np.asarray(raw, dtype=float), q_near)
            if q is None or not self._verify(q, T_world_tcp):
                continue
            if not any(np.allclose(q, f, atol=1e-7) for f in found):
                found.append(q)
        found.sort(key=lambda q: float(np.linalg.norm(q - q_near)))
        return found

    def ik_nearest(self, T_world_tcp: np.ndarray, q_near_rad: np.ndarray) -> np.ndarray:
        """The IK branch nearest ``q_near_rad`` inside the joint limits, verified by FK.

        Raises :class:`InfeasibleError` with the reason when there is none.
        """
        solutions = self.ik_all(T_world_tcp, q_near_rad)
        if not solutions:
            raise InfeasibleError(
                Failure(FailureKind.UNREACHABLE, self.unreachable_reason(T_world_tcp))
            )
        return solutions[0]

    def ik_track(self, T_world_tcp: np.ndarray, q_prev_rad: np.ndarray) -> np.ndarray | None:
        """The IK solution nearest ``q_prev_rad`` (largest joint difference), for tracking a
        path sample by sample; None when there is none inside the limits."""
        T_base_flange = (
            invert(self.T_world_base) @ np.asarray(T_world_tcp) @ invert(self.T_flange_tcp)
        )
        raw = self._solve(T_base_flange)
        if not raw:
            return None
        q_prev = np.asarray(q_prev_rad, float)
        cand = np.array(raw)
        cand = cand + 2 * np.pi * np.round((q_prev - cand) / (2 * np.pi))
        cand[:, ELBOW] = [_unwrapped_elbow(v) for v in cand[:, ELBOW]]
        order = np.argsort(np.abs(cand - q_prev).max(axis=1))
        for k in order:
            if self.within_limits(cand[k]) and self._verify(cand[k], np.asarray(T_world_tcp)):
                return np.asarray(cand[k])
        return None

    def unreachable_reason(self, T_world_tcp: np.ndarray) -> str:
        """Why ``T_world_tcp`` has no IK solution inside the limits, with numbers."""
        reason, mm_hint = self.unreachable_why(T_world_tcp)
        return reason + mm_hint

    def unreachable_why(self, T_world_tcp: np.ndarray) -> tuple[str, str]:
        """:meth:`unreachable_reason` in its two parts, the reason and the hint that its
        lengths were written in mm (``: did you mean mm? ...``, '' when they look right),
        so a caller decides on the hint without reading the text."""
        T_base_flange = (
            invert(self.T_world_base) @ np.asarray(T_world_tcp) @ invert(self.T_flange_tcp)
        )
        p = T_base_flange[:3, 3]
        from_shoulder_m = float(np.linalg.norm(p - np.array([0.0, 0.0, self.spec.d_m[0]])))
        model = self.spec.label
        if from_shoulder_m > self.spec.reach_m:
            mm = from_shoulder_m / 1000
            hint = (
                f": did you mean mm? (read as mm, {from_shoulder_m:.2f} m is {mm:.3f} m)"
                if from_shoulder_m > 10 * self.spec.reach_m
                else ""
            )
            return (
                f"out of reach ({from_shoulder_m:.2f} m from the shoulder, "
                f"{model} reach {self.spec.reach_m:.2f} m)",
                hint,
            )
        raw = self._solve(T_base_flange)
        if len(raw) == 0:
            return (
                f"no arm configuration reaches this pose (flange {from_shoulder_m:.2f} m from the "
                f"shoulder, {model} reach {self.spec.reach_m:.2f} m; orientation or position "
                f"too close to the base axis)",
                "",
            )
        return f"all {len(raw)} IK solutions exceed the joint limits", ""

    def ik_raw(self, T_world_tcp: np.ndarray) -> list[np.ndarray]:
        """Every closed-form IK solution of ``T_world_tcp`` verified by FK, unwrapped and
        unchecked against the joint limits (for diagnostics: why each branch is refused)."""
        T_base_flange = (
            invert(self.T_world_base) @ np.asarray(T_world_tcp) @ invert(self.T_flange_tcp)
        )
        raw = [np.asarray(q, float) for q in self._solve(T_base_flange)]
        return [q for q in raw if self._verify(q, np.asarray(T_world_tcp))]

    def wrap_near(self, q_raw: np.ndarray, q_near_rad: np.ndarray) -> np.ndarray | None:
        """``q_raw`` shifted per joint by multiples of 2 pi to be nearest ``q_near_rad``
        inside the joint limits; None when some joint has no such value."""
        return self._wrap_near(np.asarray(q_raw, float), np.asarray(q_near_rad, float))

    def solve_flange(
        self, T_base_flange: np.ndarray, *, search_dropped: bool = True
    ) -> list[np.ndarray]:
        """Every closed-form branch reaching ``T_base_flange`` (the flange in the base
        frame), raw: neither wrapped, nor checked against the limits, nor verified.
        ``search_dropped=False`` skips the nudged searches of :meth:`_solve` (three times
        faster where the pose has fewer than eight branches, for callers that fall back)."""
        if search_dropped:
            return self._solve(T_base_flange)
        with _stdout_silenced():
            return list(self._ik.inverse_kinematics(np.ascontiguousarray(T_base_flange)))

    def _solve(self, T_base_flange: np.ndarray) -> list[np.ndarray]:
        """The closed-form branches. At poses where a branch sits exactly on the edge of
        its formula (UR's usual home, tool straight down with the wrist axes square, is
        one) the solver's rounding can drop that branch; fewer than eight branches are
        searched again at poses ``IK_NUDGE`` off (about the flange Z, along its Y), and
        what is found there is kept when FK verifies it against the pose asked for."""
        with _stdout_silenced():
            raw = list(self._ik.inverse_kinematics(np.ascontiguousarray(T_base_flange)))
            if len(raw) >= 8:
                return raw
            for nudge in _NUDGES:
                for q in self._ik.inverse_kinematics(np.ascontiguousarray(T_base_flange @ nudge)):
                    if not any(np.allclose(q, r, atol=1e-5) for r in raw):
                        raw.append(q)
        return raw

    def _wrap_near(self, q_raw: np.ndarray, q_near: np.ndarray) -> np.ndarray | None:
        """Shift each joint by a multiple of 2 pi to be nearest q_near within limits; the
        elbow is never wrapped (:data:`ELBOW`)."""
        q = np.empty(6)
        for i in range(6):
            if i == ELBOW:
                elbow = _unwrapped_elbow(q_raw[i])
                if self.q_min_rad[i] - 1e-9 <= elbow <= self.q_max_rad[i] + 1e-9:
                    q[i] = min(max(elbow, self.q_min_rad[i]), self.q_max_rad[i])
                    continue
            best = None
            base = q_raw[i] + 2 * math.pi * round((q_near[i] - q_raw[i]) / (2 * math.pi))
            for k in (0, -1, 1, -2, 2):
                cand = base + 2 * math.pi * k
                if self.q_min_rad[i] - 1e-9 <= cand <= self.q_max_rad[i] + 1e-9 and (
                    best is None or abs(cand - q_near[i]) < abs(best - q_near[i])
                ):
                    best = cand
            if best is None:
                return None
            q[i] = min(max(best, self.q_min_rad[i]), self.q_max_rad[i])
        return q

    def _verify(self, q: np.ndarray, T_world_tcp: np.ndarray) -> bool:
        T = self.T_world_tcp(q)
        dp = np.linalg.norm(T[:3, 3] - T_world_tcp[:3, 3])
        dR = rotation_angle_rad(T[:3, :3].T @ np.asarray(T_world_tcp)[:3, :3])
        return bool(dp < IK_TOLERANCE_M * 10 and dR < IK_TOLERANCE_RAD * 10)


#: the elbow's joint index. Its angle is kept in [-pi, pi]: the forearm folds onto the upper
#: arm at +-pi, so an elbow at 269.8 deg is -90.2 deg reached the wrong way round, through
#: the upper arm (a joint move there swept the forearm through the arm, and the planner
#: blamed the fixture it met on the way); the other joints wrap freely
ELBOW = 2


def _unwrapped_elbow(value_rad: float) -> float:
    """The elbow angle ``value_rad`` in [-pi, pi] (the same configuration)."""
    return float(math.remainder(float(value_rad), 2 * math.pi))


def rotation_angle_rad(R: np.ndarray) -> float:
    """Angle of the rotation matrix ``R`` in radians, robust near 0 and pi."""
    c = (np.trace(R) - 1.0) / 2.0
    s = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return float(math.atan2(s, c))


@contextlib.contextmanager
def _stdout_silenced() -> Iterator[None]:
    """Silence file descriptor 1 for the duration: ur-analytic-ik prints a warning on
    std::cout for every degenerate branch it filters, which would corrupt ``--json``."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _ik_module(model_name: str) -> Any:  # a ur_analytic_ik solver module (untyped)
    import ur_analytic_ik

    try:
        return getattr(ur_analytic_ik, model_name)
    except AttributeError:
        raise InfeasibleError(
            Failure(FailureKind.MODEL, f"no closed-form IK for robot model {model_name!r}")
        ) from None


def _nudge(angle_rad: float, y_m: float) -> np.ndarray:
    c, s_ = math.cos(angle_rad), math.sin(angle_rad)
    T = np.eye(4)
    T[:2, :2] = ((c, -s_), (s_, c))
    T[1, 3] = y_m
    return T


_NUDGES = (_nudge(IK_NUDGE, 0.0), _nudge(0.0, IK_NUDGE))
