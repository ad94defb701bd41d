"""The ``align`` step (SPEC section 12): look, correct, look again.

Each look renders or grabs the camera's picture, finds the marker and computes where the
target frame really is: ``F_actual = T_world_camera @ T_camera_marker @ inv(T_frame_marker)``,
so the correction in the frame's own axes is ``C = inv(F) @ F_actual``. A correction outside
the step's ``max_correction`` box fails the step (3: ``check`` proved only that box). Else,
when ``C`` differs from the correction already applied by more than ``tolerance``, the TCP
makes a short straight move that carries the camera with the correction (planned from
where the arm stands and verified like any other motion) and looks again; at most
``attempts`` looks. The correction stands in ``ctx.notes["align"][FRAME]``:
:func:`cellrunner.execution.correction.corrected` moves the later steps aimed at that
frame by it.
"""

from __future__ import annotations

import math

import numpy as np

from cellrunner.execution.context import Hold, JobContext
from cellrunner.execution.steps import OK, Outcome, StepGen, run_motion
from cellrunner.model.codes import ResultCode
from cellrunner.model.geometry import rpy_deg_of
from cellrunner.model.step import Step, StepKind
from cellrunner.model.task import LinearArgs

#: the arm stands still this long before each look (s)
SETTLE_S = 0.1
#: TCP speed of the correcting moves (m/s)
CORRECTION_SPEED_MPS = 0.05


def run_align(ctx: JobContext, step: Step) -> StepGen:
    from cellrunner.vision.marker import find_corners, frame_correction

    grab = getattr(ctx.backend, "camera_image", None)
    if grab is None:
        return Outcome.failed(
            ResultCode.PLACE_FAILED,
            f"align: this robot backend gives no {step.args.camera!r} image",
        )
    args, x = step.args, step.extra
    F = x["T_world_frame"]
    applied = np.eye(4)
    low, high = args.box()
    # with no correction allowed in z, rx and ry the marker lies in its nominal plane
    planar = high[2] == 0 and high[3] == 0 and high[4] == 0
    for look in range(1, args.attempts + 1):
        t0 = ctx.now_s
        while ctx.now_s - t0 < SETTLE_S:
            ctx.hold = Hold(t0, until_s=SETTLE_S)
            yield
        q = ctx.last_state.q_rad
        T_world_camera = (
            ctx.motions.tcp_pose(q) @ x["T_tcp_camera"]
            if x["T_tcp_camera"] is not None
            else x["T_world_camera"]
        )
        corners = find_corners(grab(args.camera), args.marker)
        C = (
            None
            if corners is None
            else frame_correction(
                corners, args.marker, x["K"], x["distortion"], T_world_camera, F, planar
            )
        )
        if C is None:
            return Outcome.failed(
                ResultCode.PLACE_FAILED,
                f"align: camera {args.camera!r} does not see marker {args.marker.id} "
                f"({args.marker.dictionary}), look {look}",
            )
        six = [*C[:3, 3], *rpy_deg_of(C[:3, :3])]
        outside = [
            f"{axis} {v * (1 if i >= 3 else 1000):+.1f} {'deg' if i >= 3 else 'mm'}"
            for i, (axis, v, a, b) in enumerate(
                zip(("x", "y", "z", "rx", "ry", "rz"), six, low, high, strict=True)
            )
            if not a - 1e-9 <= v <= b + 1e-9
        ]
        if outside:
            return Outcome.failed(
                ResultCode.PLACE_FAILED,
                f"align: the part at {step.name!r} lies beyond max_correction ({', '.join(outside)})",
            )
        ctx.notes.setdefault("align", {})[step.name] = C
        moved_m, turned_deg = _distance(np.linalg.inv(applied) @ C)
        if moved_m <= args.tolerance.xyz and turned_deg <= args.tolerance.rpy:
            ctx.notes.setdefault("align_looks", {})[step.name] = look
            return OK
        if look == args.attempts:
            return Outcome.failed(
                ResultCode.PLACE_FAILED,
                f"align: the marker is still {moved_m * 1000:.1f} mm and {turned_deg:.1f} deg "
                f"from where the step expects it after {look} looks (tolerance "
                f"{args.tolerance.xyz * 1000:g} mm, {args.tolerance.rpy:g} deg)",
            )
        T_goal = F @ C @ np.linalg.inv(applied) @ np.linalg.inv(F) @ ctx.motions.tcp_pose(q)
        move = Step(
            step.index,
            StepKind.LINEAR,
            step.name,
            LinearArgs(to=step.name, speed=CORRECTION_SPEED_MPS),
            step.file_path,
            step.macro,
            T_goal,
        )
        outcome = yield from run_motion(ctx, move, resume=True)
        if not outcome.ok:
            return outcome
        applied = C
    return OK  # not reached: the last look returns


def _distance(T: np.ndarray) -> tuple[float, float]:
    """(translation m, rotation angle deg) of a pose."""
    cos = (float(np.trace(T[:3, :3])) - 1.0) / 2.0
    return float(np.linalg.norm(T[:3, 3])), math.degrees(math.acos(max(-1.0, min(1.0, cos))))
