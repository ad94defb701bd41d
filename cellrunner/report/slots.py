"""The per-slot planned cycle table: every slot of the task's pattern planned as ``check``
plans it (from the plan cache when ``check`` already did), for line balancing."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cellrunner.model.load import LoadedTask
    from cellrunner.model.params import ParamValue
    from cellrunner.planning.world import CellWorld


@dataclass(frozen=True)
class SlotCycle:
    """One slot: its planned cycle time (s, None when infeasible), per-step planned
    durations (s) by step index, and the first error when infeasible."""

    slot: int
    cycle_s: float | None
    steps_s: dict[int, float]
    error: str = ""


def slot_cycles(
    world: CellWorld, task: LoadedTask, params: dict[str, ParamValue]
) -> tuple[str, list[SlotCycle]] | None:
    """(param name, one row per slot) for the task's first pattern param; None when the
    task has no pattern."""
    from cellrunner.model.expand import pattern_params
    from cellrunner.planning.job_plan import plan_job

    patterns = pattern_params(task)
    if not patterns:
        return None
    name, slots = next(iter(patterns.items()))
    rows = []
    for slot in slots:
        plan = plan_job(world, task, {**params, name: slot}, world.q_home_rad)
        steps = {r.step.index: r.duration_s for r in plan.task_plan.rows}
        rows.append(
            SlotCycle(
                slot,
                plan.cycle_time_s if plan.ok else None,
                steps,
                plan.errors[0] if plan.errors else "",
            )
        )
    return name, rows


def worst(rows: list[SlotCycle]) -> SlotCycle | None:
    feasible = [(r.cycle_s, i) for i, r in enumerate(rows) if r.cycle_s is not None]
    return rows[max(feasible, key=lambda f: f[0])[1]] if feasible else None
