"""The arm's servo input between two controller set-points, when a controller period
spans several physics steps (CB3: 125 Hz against a 2 ms step)."""

from __future__ import annotations

import numpy as np


def hermite_table(substeps: int, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Matrices (substeps x 4) giving position and speed at the end of each physics step
    from (q0, qd0, q1, qd1) of a cubic Hermite segment over one period."""
    tau = np.arange(1, substeps + 1) / substeps
    T = period_s
    pos = np.stack(
        [
            2 * tau**3 - 3 * tau**2 + 1,
            (tau**3 - 2 * tau**2 + tau) * T,
            -2 * tau**3 + 3 * tau**2,
            (tau**3 - tau**2) * T,
        ],
        axis=1,
    )
    vel = np.stack(
        [
            (6 * tau**2 - 6 * tau) / T,
            3 * tau**2 - 4 * tau + 1,
            (-6 * tau**2 + 6 * tau) / T,
            3 * tau**2 - 2 * tau,
        ],
        axis=1,
    )
    return pos, vel
