"""What a parallel gripper's jaws hold by friction: one rule for ``check`` and the twin
(issue 33).

The pads clamp the part along the TCP's X axis, each pushing ``JAW_GRIP_FORCE_N``; across
that axis (the TCP's Y and Z) the part is held by the pads' friction alone, up to
``2 * mu * JAW_GRIP_FORCE_N``. ``mu`` is the larger of the pads' ``JAW_PAD_FRICTION`` and
the part's ``friction``: the twin's contacts combine the two geoms' coefficients that
way (MuJoCo's default). The force the pads must hold is the part's mass times its
centre's acceleration, less gravity; its part across the jaw axis over what friction
holds slides the part in the jaws (seed 1144 of the generator: 5.4 mm on a fast carry).
A load over it for a few milliseconds slides the part a fraction of a millimetre: what counts is how
far it slides (:func:`slip_m`), against ``JAW_SLIP_M``.
The twin builds its pads with these numbers (:mod:`cellrunner.sim.description`);
``check`` predicts the load along every carrying move (:mod:`cellrunner.planning.jaw_hold`).
"""

from __future__ import annotations

import numpy as np

#: the force each jaw presses the part with (N)
JAW_GRIP_FORCE_N = 40.0
#: friction coefficient of the pads
JAW_PAD_FRICTION = 1.0
#: how far a part may slide in the jaws over a carrying move before check refuses it (m)
JAW_SLIP_M = 0.001


def grip_friction(part_friction: float) -> float:
    """The friction coefficient between the pads and a part of ``part_friction``."""
    return max(JAW_PAD_FRICTION, float(part_friction))


def jaws_hold_N(part_friction: float) -> float:
    """The force across the jaw axis the two pads hold by friction (N)."""
    return 2.0 * grip_friction(part_friction) * JAW_GRIP_FORCE_N


def slip_load_N(f_on_part_N: np.ndarray, jaw_axis: np.ndarray) -> np.ndarray:
    """The force the pads' friction must hold (N): the part of the force of the tool on
    the part ``f_on_part_N`` (..., 3) across the jaw axis ``jaw_axis`` (..., 3, unit)."""
    f = np.asarray(f_on_part_N, float)
    x = np.asarray(jaw_axis, float)
    along = np.sum(f * x, axis=-1)
    return np.asarray(np.linalg.norm(f - along[..., None] * x, axis=-1))


def slip_m(loads_N: np.ndarray, holds_N: float, mass_kg: float, period_s: float) -> np.ndarray:
    """How far the part has slid in the jaws at each period (m): while the load beats
    what friction holds, the excess accelerates it against the pads; once under, friction
    brakes it with the margin, until it sticks again."""
    loads = np.asarray(loads_N, float)
    out = np.empty_like(loads)
    v_mps, x_m = 0.0, 0.0
    for i, load in enumerate(loads):
        v_mps = max(0.0, v_mps + (float(load) - holds_N) / mass_kg * period_s)
        x_m += v_mps * period_s
        out[i] = x_m
    return out
