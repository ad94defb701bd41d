"""``check`` verifies a task's ``on_error`` steps before any job runs (SPEC section 11).

on_error runs after a failure, from wherever the arm stood when the job failed. The plan
knows the states a failure can leave the arm in (the configuration, the tool mounted, the
part carried): the start, the end of every step it planned, and states in the middle of
every joint move (a protective stop, a part lost in a move: there with the part and
without it; a straight move's states are near its ends). A guarded line (``move_until_contact``) ends where it touches, not at its full
travel, and the straight move that follows may leave that contact. From each distinct
state the on_error steps are planned and verified in order, as the runner runs them:
every motion under the limits x margin, the TCP cap and collisions (with the part still
in the gripper where the job held one), and a step that fails there leaves the arm where
it stood for the next one, as at run time.

on_error is best-effort recovery: a step that cannot run from a state is a warning
(``check`` shows it, ``--json`` in ``warnings``) when the rest of the cleanup, verified
from where the arm then stands, still brings the arm to the cleanup's end (its last
motion runs from there): a ``retreat`` from the middle of a joint move near a
singularity, followed by ``move: home``. At run time that step fails its plan, is
skipped, and the rest runs. It is infeasible only from a state where the cleanup's last
motion cannot run.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Failure
from cellrunner.model.geometry import Placed
from cellrunner.model.step import Step, StepKind
from cellrunner.planning.collision import ContactAllowance
from cellrunner.planning.group_timing import _time_and_verify
from cellrunner.planning.task_plan import (
    StepPlan,
    StepPlanner,
    TaskPlan,
    _at,
)
from cellrunner.planning.world import CellWorld, placed_key

#: on_error results remembered per world (start states x steps), oldest out
ON_ERROR_MEMO_SIZE = 256


@dataclass(frozen=True)
class _Start:
    """A state a failure can leave the arm in: after ``label`` (a step, or the start)."""

    label: str
    q_rad: np.ndarray
    world: CellWorld
    part: Placed | None
    contact: tuple[ContactAllowance, ...] = ()  # a guarded line's, which a retreat leaves


def verify_on_error(
    plan: TaskPlan, cleanup: list[Step]
) -> tuple[list[StepPlan], list[Failure], list[Failure]]:
    """One row per on_error step: ``ok`` with the number of states it was verified from,
    or ``failed`` naming the first state it fails from and the reason (and how many
    other states fail too); a failure per failed row; and a warning per step skipped
    from some states (best-effort recovery: a step that cannot run from a state, while
    the rest of the cleanup, planned from where the arm then stands, still brings the
    arm to the cleanup's end: its last motion). Only a feasible plan has states to start
    from. What one state gives is remembered by the world (the slots of a pattern share
    most of their states)."""
    rows = [StepPlan(s) for s in cleanup]
    if not cleanup or not plan.ok:
        for row in rows:
            row.status = "not planned"
        return rows, [], []
    starts = _starts(plan)
    failures: dict[int, list[Failure]] = {s.index: [] for s in cleanup}
    skipped: dict[int, list[Failure]] = {s.index: [] for s in cleanup}
    steps_key = _steps_key(cleanup)
    last_motion = next((s.index for s in reversed(cleanup) if s.is_motion), None)
    for start in starts:
        failed_here = _failures_from(start, cleanup, steps_key)
        reaches_end = last_motion is not None and last_motion not in failed_here
        for index, failure in failed_here.items():
            labelled = replace(failure, reason=f"{start.label}: {failure.reason}")
            (skipped if reaches_end else failures)[index].append(labelled)
    found: list[Failure] = []
    warnings: list[Failure] = []
    for row in rows:
        failed, passed_by = failures[row.step.index], skipped[row.step.index]
        verified = f"on_error: verified from {len(starts)} states the job can fail in"
        if not failed:
            row.status = "ok"
            row.message = verified
            if passed_by:
                row.message += (
                    f"; skipped from {len(passed_by)} of them (the steps after it bring the "
                    "arm to its end)"
                )
                warnings.append(_skipped(row, passed_by))
            continue
        row.status = "failed"
        more = len(failed) - 1
        first = failed[0]
        if more:
            first = replace(first, reason=f"{first.reason} (and from {more} more states)")
        row.message = first.summary()
        found.append(replace(first, step_index=row.step.index, step=f"on_error {row.step.label}"))
    return rows, found, warnings


def _skipped(row: StepPlan, passed_by: list[Failure]) -> Failure:
    """The warning of an on_error step that cannot run from some states: the first one
    and why, how many more, and what happens there at run time."""
    first = passed_by[0]
    more = f" (and from {len(passed_by) - 1} more states)" if len(passed_by) > 1 else ""
    return replace(
        first,
        reason=f"{first.reason}{more}; there it is skipped and the steps after it, verified "
        "from where the arm stands, bring the arm to the end of on_error",
        fix="",
        step_index=row.step.index,
        step=f"on_error {row.step.label}",
    )


def _failures_from(
    start: _Start, cleanup: list[Step], steps_key: tuple[object, ...]
) -> dict[int, Failure]:
    """The on_error steps that fail when run from ``start``: index -> its failure,
    remembered per start state and steps in the world's memo."""
    key = (_key(start.q_rad, start.world, start.part), start.contact, steps_key)
    memo = start.world.on_error_memo
    if key in memo:
        cached: dict[int, Failure] = memo[key]
        return cached
    planner = StepPlanner(start.world, np.asarray(start.q_rad, float), start.part)
    planner.contact = start.contact
    failed: dict[int, Failure] = {}
    for step in cleanup:
        q_from, part = planner.q, planner.part
        try:
            if step.is_motion:
                motion = _at(step, planner.motion, StepPlan(step))
                _time_and_verify(planner.world, motion, q_from)
            else:
                _at(step, planner.act, StepPlan(step))
        except InfeasibleError as exc:
            planner.q, planner.part = q_from, part  # nothing moved: the next step goes on
            failed[step.index] = exc.failure
    while len(memo) >= ON_ERROR_MEMO_SIZE:
        memo.pop(next(iter(memo)))  # the oldest
    memo[key] = failed
    return failed


def _steps_key(steps: list[Step]) -> tuple[object, ...]:
    """What makes on_error steps the same for planning: index, kind, arguments, targets."""
    return tuple(
        (
            s.index,
            s.kind,
            s.name,
            repr(s.args),
            None if s.T_world_tcp is None else np.round(s.T_world_tcp, 9).tobytes(),
            s.q_goal_deg,
            repr(sorted(s.extra.items())),
        )
        for s in steps
    )


#: joint travel (rad, the largest joint's) between the mid-motion states taken of a motion
MID_STATE_STEP_RAD = 1.0
#: mid-motion states taken of one motion at most
MID_STATES_MAX = 3


def _starts(plan: TaskPlan) -> list[_Start]:
    """The distinct states at the start, at the end of every planned step (a guarded
    line's where it touches), and in the middle of every joint move (with the part it
    carries and, where it carries one, without it)."""
    q, world, part = np.asarray(plan.q_start_rad, float), plan.world, None
    states = [_Start("from the start", q, world, part)]
    seen = {_key(q, world, part)}

    def add(start: _Start) -> None:
        key = _key(start.q_rad, start.world, start.part)
        if key not in seen:
            seen.add(key)
            states.append(start)

    # the contact a guarded line stopped at, which the steps after it that do not move
    # (an output, a wait, a grip) still stand at: (q, allowances, label)
    touched: tuple[np.ndarray, tuple[ContactAllowance, ...], str] | None = None
    for row in plan.rows:
        before, world = world, row.world or world
        samples = row.trajectory.q_rad if row.trajectory is not None else None
        if touched is not None and samples is None:
            part = row.carrying
            q_touch, allowances, at = touched
            add(_Start(f"from the end of {row.step.label}, {at}", q_touch, world, part, allowances))
            continue
        touched = None
        if samples is not None and len(samples) > 2 and row.step.is_planned:
            for k in _middle(samples):
                where = f"from the middle of {row.step.label}"
                add(_Start(where, samples[k], world, row.carrying))
                if row.carrying is not None:
                    lost = world.without_waiting(row.carrying.name)
                    add(_Start(f"{where}, the part lost", samples[k], lost, None))
        if row.q_end_rad is not None:
            q = np.asarray(row.q_end_rad, float)
        part = row.carrying
        if row.step.kind == StepKind.MOVE_UNTIL_CONTACT and samples is not None:
            touch = _touch(world, samples, part)
            if touch is not None:
                label = f"from the contact of {row.step.label}"
                add(_Start(label, touch, world, part, tuple(row.allowances)))
                touched = (touch, tuple(row.allowances), f"at the contact of {row.step.label}")
                continue
        # a release that fails (its confirm input never came) has not set its part down
        # where the place meant to: its state is the world before it (from the step
        # after it on, the part lies where it was let go)
        at_end = before if row.step.kind == StepKind.RELEASE else world
        add(_Start(f"from the end of {row.step.label}", q, at_end, part))
    return states


def _middle(q_rad: np.ndarray) -> list[int]:
    """Sample indices inside a motion: one per ``MID_STATE_STEP_RAD`` of its joint travel
    (at least one, at most ``MID_STATES_MAX``), evenly spaced."""
    travel = float(np.abs(np.diff(q_rad, axis=0)).sum(axis=0).max())
    n = min(MID_STATES_MAX, max(1, int(travel / MID_STATE_STEP_RAD)))
    return sorted({round(len(q_rad) * (i + 1) / (n + 1)) for i in range(n)} - {0, len(q_rad) - 1})


def _touch(world: CellWorld, q_rad: np.ndarray, part: Placed | None) -> np.ndarray | None:
    from cellrunner.planning.force_plan import first_touch

    return first_touch(world.collision.carrying(part), q_rad, part is not None)


def _key(q: np.ndarray, world: CellWorld, part: Placed | None) -> tuple[object, ...]:
    return (
        np.round(q, 6).tobytes(),
        world.tool_key,
        placed_key(world.placed),
        tuple(sorted(world.gone)),
        None if part is None else (part.name, np.round(part.T_parent_shape, 6).tobytes()),
    )
