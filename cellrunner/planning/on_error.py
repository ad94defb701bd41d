"""``check`` verifies a task's ``on_error`` steps before any job runs (SPEC section 11).

on_error runs after a failure, from wherever the arm stood when the job failed. The plan
knows the states a failure can leave the arm in at least at the end of every step it
planned (the configuration, the tool mounted, the part carried) and at the start; from
each distinct one the on_error steps are planned and verified in order, as the runner
runs them: every motion under the limits x margin, the TCP cap and collisions (with the
part still in the gripper where the job held one), and a step that fails there leaves
the arm where it stood for the next one, as at run time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import Placed
from cellrunner.model.step import Step
from cellrunner.planning.task_plan import (
    StepFailure,
    StepPlan,
    TaskPlan,
    _at,
    _StepPlanner,
    _time_and_verify,
)
from cellrunner.planning.world import CellWorld

#: on_error results remembered per world (start states x steps), oldest out
ON_ERROR_MEMO_SIZE = 256


@dataclass(frozen=True)
class _Start:
    """A state a failure can leave the arm in: after ``label`` (a step, or the start)."""

    label: str
    q_rad: np.ndarray
    world: CellWorld
    part: Placed | None


def verify_on_error(
    plan: TaskPlan, cleanup: list[Step]
) -> tuple[list[StepPlan], list[StepFailure]]:
    """One row per on_error step: ``ok`` with the number of states it was verified from,
    or ``failed`` naming the first state it fails from and the reason (and how many
    other states fail too); and a failure per failed row. Only a feasible plan has states
    to start from. What one state gives is remembered by the world (the slots of a
    pattern share most of their states)."""
    rows = [StepPlan(s) for s in cleanup]
    if not cleanup or not plan.ok:
        for row in rows:
            row.status = "not planned"
        return rows, []
    starts = _starts(plan)
    failures: dict[int, list[tuple[str, tuple[str, ...]]]] = {s.index: [] for s in cleanup}
    steps_key = _steps_key(cleanup)
    for start in starts:
        for index, (reason, blockers) in _failures_from(start, cleanup, steps_key).items():
            failures[index].append((f"{start.label}: {reason}", blockers))
    found: list[StepFailure] = []
    for row in rows:
        failed = failures[row.step.index]
        if not failed:
            row.status = "ok"
            row.message = f"on_error: verified from {len(starts)} states the job can fail in"
            continue
        row.status = "failed"
        more = len(failed) - 1
        row.message = failed[0][0] + (f" (and from {more} more states)" if more else "")
        found.append(StepFailure(row.step.index, row.message, failed[0][1]))
    return rows, found


def _failures_from(
    start: _Start, cleanup: list[Step], steps_key: tuple[object, ...]
) -> dict[int, tuple[str, tuple[str, ...]]]:
    """The on_error steps that fail when run from ``start``: index -> (reason, blockers),
    remembered per start state and steps in the world's memo."""
    key = (_key(start.q_rad, start.world, start.part), steps_key)
    memo = start.world.on_error_memo
    if key in memo:
        cached: dict[int, tuple[str, tuple[str, ...]]] = memo[key]
        return cached
    planner = _StepPlanner(start.world, np.asarray(start.q_rad, float), start.part)
    failed: dict[int, tuple[str, tuple[str, ...]]] = {}
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
            failed[step.index] = (exc.reason, exc.blockers)
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


def _starts(plan: TaskPlan) -> list[_Start]:
    """The distinct states at the start and at the end of every planned step."""
    q, world, part = np.asarray(plan.q_start_rad, float), plan.world, None
    states = [_Start("from the start", q, world, part)]
    seen = {_key(q, world, part)}
    for row in plan.rows:
        if row.q_end_rad is not None:
            q = np.asarray(row.q_end_rad, float)
        world, part = row.world or world, row.carrying
        key = _key(q, world, part)
        if key not in seen:
            seen.add(key)
            states.append(_Start(f"from the end of {row.step.label}", q, world, part))
    return states


def _key(q: np.ndarray, world: CellWorld, part: Placed | None) -> tuple[object, ...]:
    return (
        np.round(q, 6).tobytes(),
        world.tool_key,
        None if part is None else (part.name, np.round(part.T_parent_shape, 6).tobytes()),
    )
