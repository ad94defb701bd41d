"""The ``align`` step (SPEC section 12): look, correct, look again.

Each look asks the job's eye (``ctx.eye``, the cameras) for the marker and computes where
the target frame really is, as a correction ``C`` in the frame's own axes (the frame found
is ``F @ C``; :func:`frame_correction`). A correction outside the step's
``max_correction`` box fails the step (3: ``check`` proved only that box). Else, when
``C`` differs from the correction already applied by more than ``tolerance``, the TCP
makes a short straight move that carries the camera with the correction (planned from
where the arm stands and verified like any other motion) and looks again; at most
``attempts`` looks. The correction stands in ``ctx.notes["align"][FRAME]``:
:func:`cellrunner.execution.correction.corrected` moves the later steps aimed at that
frame by it.
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np

from cellrunner.execution.context import Hold, JobContext
from cellrunner.execution.outcome import Outcome, StepGen
from cellrunner.execution.steps import run_motion
from cellrunner.model.align import Marker, Sighting
from cellrunner.model.codes import ResultCode
from cellrunner.model.geometry import pose_matrix, rpy_deg_of
from cellrunner.model.step import Step
from cellrunner.planning.align_correction import (
    correcting_goal,
    correcting_move,
    pose_distance,
    within_tolerance,
)

#: the arm stands still this long before each look (s)
SETTLE_S = 0.1
AXES = ("x", "y", "z", "rx", "ry", "rz")


def run_align(ctx: JobContext, step: Step) -> StepGen:
    """Look, correct, look again (at most ``attempts`` looks), leaving the correction of the
    target frame (in its own axes) in ``ctx.notes["align"][FRAME]``; the step's Outcome."""
    args, x = step.args, step.extra
    if ctx.eye is None:
        return Outcome.failed(
            ResultCode.PLACE_FAILED, f"align: no image from camera {args.camera!r} here"
        )
    F = x["T_world_frame"]
    applied = np.eye(4)
    for look in range(1, args.attempts + 1):
        yield from _settle(ctx)
        q = ctx.last_state.q_rad
        C = _look(ctx, step, q, look)
        if isinstance(C, Outcome):
            return C
        within = _within_box(step, C, applied, look)
        if isinstance(within, Outcome):
            return within
        C, six = within
        ctx.notes.setdefault("align", {})[step.name] = C
        change = np.linalg.inv(applied) @ C
        if within_tolerance(step, change):
            return Outcome(True, ResultCode.OK, f"corrected by {_pose_text(six)} in {look} looks")
        if look == args.attempts:
            moved_m, turned_deg = pose_distance(change)
            return Outcome.failed(
                ResultCode.PLACE_FAILED,
                f"align: the marker is still {moved_m * 1000:.1f} mm and {turned_deg:.1f} deg "
                f"from where the step expects it after {look} looks (tolerance "
                f"{args.tolerance.xyz * 1000:g} mm, {args.tolerance.rpy:g} deg)",
            )
        T_goal = correcting_goal(F, C, applied, ctx.motions.tcp_pose(q))
        outcome = yield from run_motion(ctx, correcting_move(step, T_goal), resume=True)
        if not outcome.ok:
            return outcome
        applied = C
    raise AssertionError("not reached: the last look returns")


def _settle(ctx: JobContext) -> Generator[None, None, None]:
    """Hold the arm still for SETTLE_S (s), one tick at a time, before a look."""
    t0 = ctx.now_s
    while ctx.now_s - t0 < SETTLE_S:
        ctx.hold = Hold(t0, until_s=SETTLE_S)
        yield


def _look(ctx: JobContext, step: Step, q_rad: np.ndarray, look: int) -> np.ndarray | Outcome:
    """One look with the arm at ``q_rad``: the correction ``C`` of the target frame, in its
    own axes (4 x 4, m), or a failed Outcome when the camera does not see the marker."""
    args, x = step.args, step.extra
    assert ctx.eye is not None
    _, high = args.box()
    # with no correction allowed in z, rx and ry the marker lies in its nominal plane
    planar = high[2] == 0 and high[3] == 0 and high[4] == 0
    T_world_camera = (
        ctx.motions.tcp_pose(q_rad) @ x["T_tcp_camera"]
        if x["T_tcp_camera"] is not None
        else x["T_world_camera"]
    )
    seen = ctx.eye.sight(args.camera, args.marker)
    F = x["T_world_frame"]
    C = None if seen is None else frame_correction(seen, args.marker, T_world_camera, F, planar)
    if C is None:
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"align: camera {args.camera!r} does not see marker {args.marker.id} "
            f"({args.marker.dictionary}), look {look}",
        )
    return C


def _within_box(
    step: Step, C: np.ndarray, applied: np.ndarray, look: int
) -> tuple[np.ndarray, list[float]] | Outcome:
    """The correction to apply and its six numbers (x, y, z in m; rx, ry, rz in deg):
    ``C`` itself inside the step's max_correction box, else the nearest correction inside;
    a failed Outcome when the part lies beyond the box for good."""
    args = step.args
    low, high = args.box()
    six = [*C[:3, 3], *rpy_deg_of(C[:3, :3])]
    outside = [
        f"{axis} {v * (1 if i >= 3 else 1000):+.1f} {'deg' if i >= 3 else 'mm'}"
        for i, (axis, v, a, b) in enumerate(zip(AXES, six, low, high, strict=True))
        if not a - 1e-9 <= v <= b + 1e-9
    ]
    if not outside:
        return C, six
    # a look from off-centre may read a part at the box's edge just beyond it:
    # within the tolerance of the edge it is at the edge; farther, the arm moves to
    # the nearest correction inside and looks again; beyond it from there, it is
    inside = pose_matrix(np.clip(six[:3], low[:3], high[:3]), np.clip(six[3:], low[3:], high[3:]))
    excess_m, excess_deg = pose_distance(np.linalg.inv(inside) @ C)
    at_edge = excess_m <= args.tolerance.xyz and excess_deg <= args.tolerance.rpy
    gap_m, gap_deg = pose_distance(np.linalg.inv(applied) @ inside)
    # already there (within tolerance): the edge is as far as a correction goes
    stuck = gap_m <= args.tolerance.xyz and gap_deg <= args.tolerance.rpy
    if not at_edge and (look == args.attempts or stuck):
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"align: the part at {step.name!r} lies beyond max_correction ({', '.join(outside)})",
        )
    return inside, [*inside[:3, 3], *rpy_deg_of(inside[:3, :3])]


def frame_correction(
    seen: Sighting,
    marker: Marker,
    T_world_camera: np.ndarray,
    T_world_frame: np.ndarray,
    planar: bool,
) -> np.ndarray | None:
    """Where the frame the marker sits in really is, as a correction ``C`` in the frame's
    own axes (``T_world_frame @ C`` is the frame found).

    ``planar``: the marker lies in its nominal plane and only x, y and the turn about the
    frame's Z are measured: each corner's ray is cut with that plane and a rigid 2-D fit
    maps the nominal corners onto the cuts (a small marker's tilt and depth from one view
    are far less sure than where it lies in a known plane). Else the full pose (IPPE)."""
    T_frame_marker = marker.pose.matrix()
    if not planar:
        if seen.T_camera_marker is None:
            return None
        T_found = T_world_camera @ seen.T_camera_marker @ np.linalg.inv(T_frame_marker)
        return np.asarray(np.linalg.inv(T_world_frame) @ T_found)
    T_frame_camera = np.linalg.inv(T_world_frame) @ T_world_camera
    d = seen.rays @ T_frame_camera[:3, :3].T  # in the frame's axes
    o = T_frame_camera[:3, 3]
    h = float(marker.size) / 2
    corners = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]])
    nominal = corners @ T_frame_marker[:3, :3].T + T_frame_marker[:3, 3]
    z0 = float(np.mean(nominal[:, 2]))
    if np.any(np.abs(d[:, 2]) < 1e-9):
        return None
    cuts = o + d * ((z0 - o[2]) / d[:, 2])[:, None]
    a, b = nominal[:, :2], cuts[:, :2]
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    H = (a - ca).T @ (b - cb)
    yaw = float(np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1]))
    R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    C = np.eye(4)
    C[:2, :2] = R
    C[:2, 3] = cb - R @ ca
    return C


def _pose_text(six: list[float]) -> str:
    """``xyz [+8.0, +6.0, +0.0] mm rpy [+0.00, +0.00, +4.00] deg``"""
    xyz = ", ".join(f"{v * 1000:+.1f}" for v in six[:3])
    rpy = ", ".join(f"{v:+.2f}" for v in six[3:])
    return f"xyz [{xyz}] mm rpy [{rpy}] deg"
