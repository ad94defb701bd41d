"""What a vacuum seal holds: one rule for ``check`` and the twin (issue 33).

The cups carry the net force of the tool on the held part. That force splits into the
pull along the cup axis (towards the cups: what the seal must hold) and the shear across
it, which the lips hold by friction; the seal's load is ``pull + shear / CUP_FRICTION``
(N). A seal leaks for a while before it lets go, so the load is low-pass filtered
(time constant ``PULL_TAU_S``): a jolt of a few milliseconds does not tear a part off, a
sustained pull over the gripper's ``holding_force`` does. The twin measures the force
(:mod:`cellrunner.sim.vacuum`); ``check`` predicts it from the part's mass and the
planned accelerations (:mod:`cellrunner.planning.suction_hold`).
"""

from __future__ import annotations

import numpy as np

#: friction of a sealed cup against shear (lateral force holds up to this x the pull rating)
CUP_FRICTION = 0.5
#: time constant (s) of the low-pass on the seal's load
PULL_TAU_S = 0.05


def seal_load_N(f_on_part_N: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The seal's load (N) for the force of the tool on the part ``f_on_part_N`` (..., 3)
    and the cup axis ``axis`` (..., 3, unit, out of the cups into the part)."""
    f = np.asarray(f_on_part_N, float)
    a = np.asarray(axis, float)
    pull = np.sum(f * -a, axis=-1)
    shear = np.linalg.norm(f + pull[..., None] * a, axis=-1)
    return np.asarray(np.maximum(pull, 0.0) + shear / CUP_FRICTION)


def filter_step(previous_N: float, load_N: float, period_s: float) -> float:
    """One period of the seal's low-pass: the filtered load after ``load_N``."""
    alpha = min(1.0, period_s / PULL_TAU_S)
    return (1 - alpha) * previous_N + alpha * load_N


def filtered_N(loads_N: np.ndarray, period_s: float) -> np.ndarray:
    """The seal's filtered load over consecutive periods (starting at the first load)."""
    loads = np.asarray(loads_N, float)
    out = np.empty_like(loads)
    lp = float(loads[0]) if len(loads) else 0.0
    for i, load in enumerate(loads):
        lp = filter_step(lp, float(load), period_s)
        out[i] = lp
    return out
