"""Fits into holes: what ``check`` proves of an ``insert`` (and of a ``descend`` into a
tight fit) besides its clearances (issue 33).

**The insert must reach its depth.** Its held part (or, carrying nothing, its tool) meets
nothing that is not named in ``contact:`` before the shallow end of ``expect_depth``: a
fixture met sooner (the floor of a hole 8 mm deep under a 25 mm insert) stops the insert
there, outside its window, and the place fails (3) on every backend.

**A fit that jams is refused.** ``contact:`` lets the part and the tool touch the named
fixtures (the walls of a hole) and slide along them, not press into them: a part that
overlaps a named fixture by more than :data:`JAM_TOLERANCE_M` jams, on one fixture (its
tip over the rim of the hole: no chamfer guides it in, since the arm holds the part where
the plan says) or on several at once (an interference fit). An interference fit is a
press fit only where the insert says so, ``force: {min: N, max: N}``: the insert must
build up ``min`` N (else it fails at run time), the overlap stays within
:data:`PRESS_FIT_MAX_M`, and ``max`` within the arm's force limit (:data:`ARM_FORCE_LIMIT_N`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.body import Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind

if TYPE_CHECKING:
    from cellrunner.model.step import Step
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.kinematics import ArmKinematics

#: how far a part may overlap a fixture named in ``contact:`` and still slide along it (m):
#: the proof's tolerance, not a press
JAM_TOLERANCE_M = 2e-5
#: the largest overlap (per face, m) a declared press fit (``force: {min, max}``) may have
PRESS_FIT_MAX_M = 2e-4
#: the wrist force (N) an insert may ask for: UR's default safety force limit (a protective
#: stop above it), which the twin applies too
ARM_FORCE_LIMIT_N = 150.0


def depth_along_m(kin: ArmKinematics, step: Step, q_rad: np.ndarray) -> float:
    """How far past the insert's frame the TCP stands at ``q_rad``, along its Z (m)."""
    T_end = step.T_world_tcp
    assert T_end is not None  # an insert goes to a frame
    z = T_end[:3, 2]
    p_frame = T_end[:3, 3] - float(step.args.depth) * z
    return float(np.dot(kin.T_world_tcp(q_rad)[:3, 3] - p_frame, z))


def early_stop(
    kin: ArmKinematics, step: Step, bare: CollisionModel, path: np.ndarray, carrying: bool
) -> Failure | None:
    """The failure of an insert whose mover meets a fixture not in ``contact:`` before
    the shallow end of its ``expect_depth``; None when it does not. ``bare``: the cell's
    model with the carried part and no allowances; ``path``: the line's joint samples."""
    from cellrunner.planning.force_plan import first_touch

    named = frozenset(step.args.contact or ())
    q_touch = first_touch(bare, path, carrying, exclude=named)
    if q_touch is None:
        return None
    depth_m = depth_along_m(kin, step, q_touch)
    lo_m = step.args.depth_window_m[0]
    if depth_m >= lo_m - 1e-4:
        return None  # it stops where it should: the bottom of the hole
    blocker = _nearest(bare, q_touch, carrying, named)
    mover = "held part" if carrying else "tool"
    return Failure(
        FailureKind.CONTACT,
        f"the {mover} meets {blocker.body} {_where(depth_m)} frame '{step.args.to}', "
        f"before the {lo_m * 1000:.1f} mm expect_depth asks: the insert would stop there "
        "and fail (3)",
        blockers=(blocker,),
        fix=(
            f"fix: a deeper hole ({blocker.body} at least {(lo_m - depth_m) * 1000:.1f} mm "
            "lower), a shorter insert (depth and expect_depth), or name it in contact: if "
            "the part is meant to slide along it"
        ),
        step_index=step.index,
        step=step.label,
    )


def _nearest(
    bare: CollisionModel, q_rad: np.ndarray, carrying: bool, named: frozenset[str]
) -> Blocker:
    """The obstacle (not in ``named``) nearest the mover at ``q_rad``, with its distance."""
    mover = BodyKind.PART if carrying else BodyKind.TOOL
    distances, _ = bare.pair_distances(q_rad)
    near = [
        Blocker(b, float(distances[k]))
        for k, (a, b) in enumerate(bare.pair_labels)
        if a.kind is mover and b.is_obstacle and b.name not in named
    ]
    if not near:
        return Blocker(Body(BodyKind.NOTHING, "nothing"))
    return min(near, key=lambda blocker: blocker.distance_m or 0.0)


def jam(kin: ArmKinematics, step: Step, bare: CollisionModel, path: np.ndarray) -> Failure | None:
    """The failure of a line whose part or tool presses into a fixture named in
    ``contact:`` (over a rim, or an interference fit the step does not declare as a press
    fit); None when it slides in."""
    named = frozenset(getattr(step.args, "contact", None) or ())
    if not named:
        return None
    pairs = [
        k
        for k, (a, b) in enumerate(bare.pair_labels)
        if a.kind in (BodyKind.PART, BodyKind.TOOL) and b.is_obstacle and b.name in named
    ]
    if not pairs:
        return None
    press = _press_fit_N(step)
    allowed_m = PRESS_FIT_MAX_M if press is not None else JAM_TOLERANCE_M
    q_before = np.asarray(path[0], float)
    deepest_m = 0.0
    for q in np.asarray(path, float):
        overlap_m = _overlaps(bare, pairs, q)
        deepest_m = max(deepest_m, overlap_m)
        if overlap_m <= allowed_m:
            q_before = q
            continue
        # where it begins to press in, between the samples (to 1/256 of their step)
        lo, hi = 0.0, 1.0
        for _ in range(8):
            mid = 0.5 * (lo + hi)
            if _overlaps(bare, pairs, q_before + mid * (q - q_before)) > allowed_m:
                hi = mid
            else:
                lo = mid
        distances, _ = bare.pair_distances(q)  # how deep at the first sample past it
        into = {bare.pair_labels[k]: -float(distances[k]) for k in pairs if distances[k] < 0}
        return _jam_failure(kin, step, q_before + hi * (q - q_before), into, press)
    if press is not None and deepest_m <= 0.0:
        return Failure(
            FailureKind.CONTACT,
            f"the press fit is never made: the {_mover(bare, pairs)} does not overlap "
            f"{', '.join(sorted(named))} anywhere along the insert, so its force cannot "
            f"build up to the {press[0]:g} N of force.min (it would fail, 3)",
            fix="fix: a hole narrower than the part, or no force.min if it is a sliding fit",
            step_index=step.index,
            step=step.label,
        )
    if press is not None and press[1] > ARM_FORCE_LIMIT_N:
        return Failure(
            FailureKind.JAM,
            f"the press fit asks for up to {press[1]:g} N (force.max) but the arm stops "
            f"above {ARM_FORCE_LIMIT_N:g} N (its safety force limit)",
            fix=f"fix: a fit that presses in under {ARM_FORCE_LIMIT_N:g} N (force.max)",
            step_index=step.index,
            step=step.label,
        )
    return None


def _mover(bare: CollisionModel, pairs: list[int]) -> str:
    """What moves along the line: "held part" or "tool"."""
    carried = any(bare.pair_labels[k][0].kind is BodyKind.PART for k in pairs)
    return "held part" if carried else "tool"


def _overlaps(bare: CollisionModel, pairs: list[int], q_rad: np.ndarray) -> float:
    """The deepest overlap (m, 0 when none) over ``pairs`` at ``q_rad``."""
    distances, _ = bare.pair_distances(q_rad)
    return max(0.0, -float(np.min(distances[pairs])))


def _press_fit_N(step: Step) -> tuple[float, float] | None:
    """The press fit ``step`` declares, (force.min, force.max) in N, or None."""
    force = getattr(step.args, "force", None)
    low = getattr(force, "min", None)
    return None if low is None else (float(low), float(force.max))  # type: ignore[union-attr]


def _jam_failure(
    kin: ArmKinematics,
    step: Step,
    q_rad: np.ndarray,
    into: dict[tuple[Body, Body], float],
    press: tuple[float, float] | None,
) -> Failure:
    """The jam at ``q_rad``: ``into`` the overlap (m) of each pair with a named fixture."""
    ranked = sorted(into.items(), key=lambda item: -item[1])
    (mover, fixture), overlap_m = ranked[0]
    where = (
        f" {max(0.0, depth_along_m(kin, step, q_rad)) * 1000:.1f} mm past frame '{step.args.to}'"
        if step.kind == "insert"
        else ""
    )
    blockers = tuple(Blocker(b, -m) for (_, b), m in ranked if m > JAM_TOLERANCE_M)
    walls = {b.body.name for b in blockers}
    if press is not None:
        reason = (
            f"{mover} is {overlap_m * 1000:.2f} mm into {fixture}{where}, more than a press "
            f"fit's {PRESS_FIT_MAX_M * 1000:.1f} mm: it jams"
        )
        fix = f"fix: a hole at most {PRESS_FIT_MAX_M * 1000:.1f} mm narrower than the part"
    elif len(walls) > 1:
        reason = (
            f"{mover} overlaps {', '.join(b.body for b in blockers)} by up to "
            f"{overlap_m * 1000:.2f} mm from{where or ' the start'} (an interference fit): "
            "it jams"
        )
        fix = (
            "fix: a hole with clearance around the part, or declare the press fit: "
            f"force: {{min: N, max: N}} (max under {ARM_FORCE_LIMIT_N:g} N)"
        )
    else:
        reason = (
            f"{mover} comes {overlap_m * 1000:.2f} mm over the rim of {fixture}{where}: "
            "contact: lets it touch the fixture, not press into it, and nothing guides it "
            "in: it jams on the rim"
        )
        fix = (
            f"fix: centre frame '{step.args.to}' over the hole (move it "
            f"{(overlap_m + 0.1 * 1e-3) * 1000:.1f} mm away from {fixture}), or a wider hole"
        )
    return Failure(
        FailureKind.JAM, reason, blockers=blockers, fix=fix, step_index=step.index, step=step.label
    )


def _where(depth_m: float) -> str:
    """``12.0 mm past`` or ``10.1 mm before`` (a frame), never a negative distance."""
    side = "past" if depth_m >= 0 else "before"
    return f"{abs(depth_m) * 1000:.1f} mm {side}"
