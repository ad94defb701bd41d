"""An ``align``'s correcting move, one definition for ``check`` and the run time.

When a look finds the target frame at ``F @ C`` (``C`` in the frame's own axes), the
run time (:mod:`cellrunner.execution.align`) moves the TCP in a straight line at
``CORRECTION_SPEED_MPS`` so that the camera moves with the correction, planned from
where the arm stands and verified like any other motion, then looks again. ``check``
plans the job for the centre and every corner of ``max_correction`` (``align:FRAME``);
for each it plans that same line from the look with the same planner and rules
(:func:`cellrunner.planning.align_proof.prove_correcting_line`), so a correction the run time would refuse there is
refused before the job runs, naming the correction and the line. The steps after the
align then start from the look (the arm's configuration there differs from the run
time's by the correction: millimetres, the same IK branches in the same order).
"""

from __future__ import annotations

import math

import numpy as np

from cellrunner.model.geometry import rpy_deg_of
from cellrunner.model.step import Step, StepKind
from cellrunner.model.task import LinearArgs

#: TCP speed of the correcting moves (m/s)
CORRECTION_SPEED_MPS = 0.05


def correcting_move(step: Step, T_goal: np.ndarray) -> Step:
    """The align ``step``'s straight TCP move (at CORRECTION_SPEED_MPS) to ``T_goal``
    (world frame, m)."""
    return Step(
        step.index,
        StepKind.LINEAR,
        step.name,
        LinearArgs(to=step.name, speed=CORRECTION_SPEED_MPS),
        step.file_path,
        step.macro,
        T_goal,
    )


def correcting_goal(
    T_world_frame: np.ndarray, C: np.ndarray, applied: np.ndarray, T_world_tcp: np.ndarray
) -> np.ndarray:
    """Where the TCP at ``T_world_tcp`` goes when the frame's correction changes from
    ``applied`` to ``C`` (both in the frame's axes): the camera moves with it."""
    F = T_world_frame
    return np.asarray(F @ C @ np.linalg.inv(applied) @ np.linalg.inv(F) @ T_world_tcp)


def pose_distance(T: np.ndarray) -> tuple[float, float]:
    """(translation m, rotation angle deg) of a pose."""
    cos = (float(np.trace(T[:3, :3])) - 1.0) / 2.0
    return float(np.linalg.norm(T[:3, 3])), math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def within_tolerance(step: Step, T: np.ndarray) -> bool:
    """The change ``T`` (4 x 4, m) is within the align's tolerance: no move is made."""
    moved_m, turned_deg = pose_distance(T)
    tolerance = step.args.tolerance
    return bool(moved_m <= float(tolerance.xyz) and turned_deg <= float(tolerance.rpy))


def correcting_goals(step: Step, T_look: np.ndarray) -> list[np.ndarray]:
    """Where the correcting line from the look ``T_look`` (T_world_tcp) ends for each
    corner of the align ``step``'s max_correction box (the lines the run time may make;
    corners within the tolerance make none)."""
    import itertools

    from cellrunner.model.geometry import pose_matrix

    low, high = step.args.box()
    axes = [(a, b) if b > a else (a,) for a, b in zip(low, high, strict=True)]
    F = step.extra["T_world_frame"]
    out = []
    for six in itertools.product(*axes):
        C = pose_matrix(six[:3], six[3:])
        if not within_tolerance(step, C):
            out.append(correcting_goal(F, C, np.eye(4), T_look))
    return out


def correction_text(C: np.ndarray) -> str:
    """``x +10.0 mm, y -10.0 mm, rz +5.0 deg`` (the axes that are not 0)."""
    six = [*(C[:3, 3] * 1000), *rpy_deg_of(C[:3, :3])]
    parts = [
        f"{axis} {v:+.1f} {'deg' if i >= 3 else 'mm'}"
        for i, (axis, v) in enumerate(zip(("x", "y", "z", "rx", "ry", "rz"), six, strict=True))
        if abs(v) > 1e-6
    ]
    return ", ".join(parts) or "none"
