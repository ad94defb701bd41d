"""Does the vacuum hold the part through the moves that carry it? (issue 33)

A part on suction cups is held by the seal's load rule of :mod:`cellrunner.model.suction`
(pull along the cup axis plus shear over friction, low-pass filtered), the rule the twin
tears parts off by. ``check`` predicts the force of the tool on the part along every
carrying move as it was timed: the part's mass times its centre's acceleration, less
gravity, and refuses the job where the filtered load exceeds the gripper's
``holding_force``: the part would tear off (a part heavier than the cups hold falls at
the lift already).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.suction import filter_step, seal_load_N

if TYPE_CHECKING:
    from cellrunner.model.expand import Step
    from cellrunner.model.geometry import Placed
    from cellrunner.model.trajectory import Trajectory
    from cellrunner.planning.world import CellWorld


class StepPlan(Protocol):
    """What the rule reads of a planned row (:class:`~.task_plan.StepPlan`)."""

    step: Step
    world: CellWorld | None
    carrying: Placed | None
    trajectory: Trajectory | None


GRAVITY_MPS2 = 9.81


def check_suction_hold(world: CellWorld, rows: Sequence[StepPlan]) -> None:
    """Raise InfeasibleError at the first carrying move whose seal load exceeds the
    vacuum gripper's holding force (the rows in order, as planned and timed)."""
    lp: float | None = None  # the filtered load, carried across consecutive moves
    for row in rows:
        w = row.world or world
        gripper = w.loaded.cell.tool.gripper
        part = row.carrying
        if gripper is None or gripper.kind != "vacuum" or part is None:
            lp = None
            continue
        holding_N = float(gripper.holding_force or 0.0)
        mass_kg = next((float(p.mass) for p in w.loaded.cell.parts if p.name == part.name), 0.0)
        if row.trajectory is None or not row.step.is_motion:
            lp = mass_kg * GRAVITY_MPS2 / 1.0  # held still: its weight, straight down the cups
            loads = np.array([lp])
            peak_i, peak = 0, lp
        else:
            loads = _loads_N(w, row, mass_kg)
            period_s = 1.0 / w.spec.rate_hz
            filtered = np.empty_like(loads)
            state = float(loads[0]) if lp is None else lp
            for i, load in enumerate(loads):
                state = filter_step(state, float(load), period_s)
                filtered[i] = state
            lp = state
            peak_i = int(np.argmax(filtered))
            peak = float(filtered[peak_i])
        if peak > holding_N:
            raise _torn_off(row, part.name, mass_kg, holding_N, peak, peak_i, len(loads))


def _loads_N(world: CellWorld, row: StepPlan, mass_kg: float) -> np.ndarray:
    """The seal's load (N) at each set-point of ``row``'s trajectory, unfiltered."""
    assert row.trajectory is not None and row.carrying is not None
    kin = world.kinematics
    q = row.trajectory.q_rad
    T = np.array([kin.T_world_tcp(qi) for qi in q])
    centre = (T @ row.carrying.T_parent_shape)[:, :3, 3]
    rate = world.spec.rate_hz
    accel = np.zeros_like(centre)
    if len(centre) >= 3:
        a = np.diff(centre, 2, axis=0) * rate * rate
        accel = np.vstack([a[:1], a, a[-1:]])
    f_on_part = mass_kg * (accel + np.array([0.0, 0.0, GRAVITY_MPS2]))
    return seal_load_N(f_on_part, T[:, :3, 2])


def _torn_off(
    row: StepPlan, part: str, mass_kg: float, holding_N: float, peak_N: float, i: int, n: int
) -> InfeasibleError:
    weight_N = mass_kg * GRAVITY_MPS2
    step = row.step
    if weight_N > holding_N:
        why = (
            f"the cups hold {holding_N:.0f} N (tool.gripper.holding_force) but part "
            f"'{part}' weighs {weight_N:.1f} N ({mass_kg:g} kg): it falls off the cups"
        )
        fix = "cups that hold more (more or larger cups, a deeper vacuum), or a lighter part"
    else:
        where = f"{100 * i / max(n - 1, 1):.0f}% into the move"
        why = (
            f"carrying part '{part}' ({mass_kg:g} kg, {weight_N:.1f} N) the move pulls "
            f"{peak_N:.1f} N on the cups {where}, over the {holding_N:.0f} N they hold "
            "(tool.gripper.holding_force): the part tears off"
        )
        fix = "a lower speed or acceleration for the moves that carry it, or stronger cups"
    return InfeasibleError(
        Failure(FailureKind.HOLD, why, fix=f"fix: {fix}", step_index=step.index, step=step.label)
    )
