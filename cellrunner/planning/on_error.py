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
    StepPlan,
    TaskPlan,
    _StepPlanner,
    _strip_label,
    _time_and_verify,
)
from cellrunner.planning.world import CellWorld


@dataclass(frozen=True)
class _Start:
    """A state a failure can leave the arm in: after ``label`` (a step, or the start)."""

    label: str
    q_rad: np.ndarray
    world: CellWorld
    part: Placed | None


def verify_on_error(plan: TaskPlan, cleanup: list[Step]) -> list[StepPlan]:
    """One row per on_error step: ``ok`` with the number of states it was verified from,
    or ``failed`` naming the first state it fails from and the reason (and how many
    other states fail too). Only a feasible plan has states to start from."""
    rows = [StepPlan(s) for s in cleanup]
    if not cleanup or not plan.ok:
        for row in rows:
            row.status = "not planned"
        return rows
    starts = _starts(plan)
    failures: dict[int, list[str]] = {s.index: [] for s in cleanup}
    for start in starts:
        planner = _StepPlanner(start.world, np.asarray(start.q_rad, float), start.part)
        for step in cleanup:
            q_from, part = planner.q, planner.part
            try:
                if step.is_motion:
                    motion = planner.motion(StepPlan(step))
                    _time_and_verify(planner.world, motion, q_from)
                else:
                    planner.act(StepPlan(step))
            except InfeasibleError as exc:
                planner.q, planner.part = q_from, part  # nothing moved: the next step goes on
                failures[step.index].append(f"{start.label}: {_strip_label(str(exc))}")
    for row in rows:
        failed = failures[row.step.index]
        if not failed:
            row.status = "ok"
            row.message = f"on_error: verified from {len(starts)} states the job can fail in"
            continue
        row.status = "failed"
        more = len(failed) - 1
        row.message = failed[0] + (f" (and from {more} more states)" if more else "")
    return rows


def on_error_errors(rows: list[StepPlan]) -> list[str]:
    """The plan errors of failed on_error rows, each naming its step."""
    return [f"on_error {r.step.label}: {r.message}" for r in rows if r.status == "failed"]


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
