"""Do the jaws hold the part through the moves that carry it? (issue 33)

A part between a parallel gripper's pads is held across the jaw axis by friction alone
(:mod:`cellrunner.model.jaw_grip`, the rule the twin's pads follow). ``check`` predicts
the force on the part along every carrying move as it was timed (the part's mass times
its centre's acceleration, less gravity) and refuses the job where its part across the
jaw axis beats what the pads' friction holds long enough to slide it more than
``JAW_SLIP_M``: it is set down off its place (or falls). The refusal says the
acceleration that would hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.jaw_grip import JAW_SLIP_M, jaws_hold_N, slip_load_N, slip_m
from cellrunner.planning.suction_hold import GRAVITY_MPS2, StepPlan

if TYPE_CHECKING:
    from cellrunner.planning.world import CellWorld


def check_jaw_hold(world: CellWorld, rows: Sequence[StepPlan]) -> None:
    """Raise InfeasibleError at the first carrying move whose load across the jaw axis
    exceeds what the pads' friction holds (the rows in order, as planned and timed)."""
    for row in rows:
        w = row.world or world
        gripper = w.loaded.cell.tool.gripper
        part = row.carrying
        if gripper is None or gripper.kind == "vacuum" or part is None:
            continue
        spec = next((p for p in w.loaded.cell.parts if p.name == part.name), None)
        if spec is None:
            continue
        mass_kg, holds_N = float(spec.mass), jaws_hold_N(spec.friction)
        if row.trajectory is None or not row.step.is_motion or len(row.trajectory.q_rad) < 3:
            accel = np.zeros((1, 3))
            axes = np.array([[1.0, 0.0, 0.0]])  # held still: only the weight, worst case
        else:
            accel, axes = _accelerations(w, row)
        loads = slip_load_N(mass_kg * (accel + np.array([0.0, 0.0, GRAVITY_MPS2])), axes)
        if float(loads.min()) > holds_N or (
            float(loads.max()) > holds_N
            and float(slip_m(loads, holds_N, mass_kg, 1.0 / w.spec.rate_hz)[-1]) > JAW_SLIP_M
        ):
            i = int(np.argmax(loads))
            raise _slides(row, part.name, mass_kg, holds_N, float(loads[i]), i, len(loads), accel)


def _accelerations(world: CellWorld, row: StepPlan) -> tuple[np.ndarray, np.ndarray]:
    """The part centre's acceleration (m/s^2) and the jaw axis (the TCP's X) at each
    set-point of ``row``'s trajectory."""
    assert row.trajectory is not None and row.carrying is not None
    kin = world.kinematics
    T = np.array([kin.T_world_tcp(qi) for qi in row.trajectory.q_rad])
    centre = (T @ row.carrying.T_parent_shape)[:, :3, 3]
    rate = world.spec.rate_hz
    a = np.diff(centre, 2, axis=0) * rate * rate
    return np.vstack([a[:1], a, a[-1:]]), T[:, :3, 0]


def _slides(
    row: StepPlan,
    part: str,
    mass_kg: float,
    holds_N: float,
    peak_N: float,
    i: int,
    n: int,
    accel: np.ndarray,
) -> InfeasibleError:
    weight_N = mass_kg * GRAVITY_MPS2
    step = row.step
    if weight_N > holds_N:
        why = (
            f"the jaws hold {holds_N:.0f} N by friction across their axis but part "
            f"'{part}' weighs {weight_N:.1f} N ({mass_kg:g} kg): it slides out of the jaws"
        )
        fix = "a gripper that clamps harder or pads of more friction, or a lighter part"
    else:
        peak_mps2 = float(np.linalg.norm(accel[min(i, len(accel) - 1)]))
        keep_mps2 = holds_N / mass_kg - GRAVITY_MPS2  # what holds whatever its direction
        where = f"{100 * i / max(n - 1, 1):.0f}% into the move"
        why = (
            f"carrying part '{part}' ({mass_kg:g} kg) the move loads the jaws {peak_N:.1f} N "
            f"across their axis {where} (the part accelerating {peak_mps2:.1f} m/s^2), over "
            f"the {holds_N:.0f} N their friction holds: the part slides in the jaws (more than "
            f"{JAW_SLIP_M * 1000:g} mm over the move)"
        )
        fix = (
            f"keep the part's acceleration under {keep_mps2:.1f} m/s^2 (a lower speed or "
            "acceleration for the moves that carry it), or a gripper that clamps harder"
        )
    return InfeasibleError(
        Failure(FailureKind.HOLD, why, fix=f"fix: {fix}", step_index=step.index, step=step.label)
    )
