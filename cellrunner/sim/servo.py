"""The arm's servo input between two controller set-points, when a controller period
spans several physics steps (CB3: 125 Hz against a 2 ms step)."""

from __future__ import annotations

from typing import Any

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


#: the zero speed set-point: ``qd_ref is ZERO6`` means no speed feed-forward was sent
#: since the last period (never written: every update rebinds)
ZERO6 = np.zeros(6)
ZERO6.setflags(write=False)


class ServoInput:
    """The arm servos' input, physics step by physics step, for a world's set-points.

    servoJ semantics: be at q_ref at the end of the period. The PD with velocity
    feed-forward settles onto its position input one physics step ahead, so that input
    is the set-point one step back along the commanded speed (plus the kv/kp feed-forward
    term). With several steps per period (CB3) the set-point is interpolated (cubic
    Hermite) across them."""

    def __init__(
        self, mj: Any, model: Any, data: Any, ff_gain: np.ndarray, substeps: int, period_s: float
    ) -> None:
        self._mj, self.model = mj, model
        self.substeps = substeps
        # Hot-path view into MjData (its buffers never move); the arm's servos come first.
        self._servo_ctrl = data.ctrl[0:6]
        self._ctrl_tmp = np.zeros(6)
        # The arm settles one physics step ahead of its servo input (measured), hence -h.
        self._ff_lead = ff_gain - period_s / substeps
        self._hermite = hermite_table(substeps, period_s)

    def step(self, data: Any, ends: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Step the physics through one period from set-point (q, qd) ``ends[0:2]`` to
        ``ends[2:4]`` (a ``qd`` that is :data:`ZERO6`: no feed-forward)."""
        q_prev_ref, qd_prev_ref, q_ref, qd_ref = ends
        k = self.substeps
        if k == 1:
            if qd_ref is ZERO6:
                self._servo_ctrl[:] = q_ref
            else:  # ctrl = q_ref + ff_lead * qd_ref, with no temporaries
                np.add(
                    np.multiply(self._ff_lead, qd_ref, self._ctrl_tmp),
                    q_ref,
                    self._servo_ctrl,
                )
            self._mj.mj_step(self.model, data)
        else:
            # cubic Hermite between the last and this set-point (positions and speeds),
            # so the servo input and its speed feed-forward are continuous (a stepped
            # feed-forward at 125 Hz shakes a gripped part loose)
            stacked = np.stack([q_prev_ref, qd_prev_ref, q_ref, qd_ref])
            q_sub = self._hermite[0] @ stacked
            qd_sub = self._hermite[1] @ stacked
            ctrl = q_sub + self._ff_lead * qd_sub
            for s in range(k):
                self._servo_ctrl[:] = ctrl[s]
                self._mj.mj_step(self.model, data)

    def inputs(
        self, q_prev: np.ndarray, qd_prev: np.ndarray, q_rad: np.ndarray, qd_rad_s: np.ndarray
    ) -> np.ndarray:
        """See :meth:`~cellrunner.sim.world.SimWorld.servo_inputs`."""
        k = self.substeps
        if k == 1:
            return np.asarray(np.add(np.multiply(self._ff_lead, qd_rad_s), q_rad))
        rows = np.empty((len(q_rad) * k, 6))
        for i in range(len(q_rad)):
            ends = np.stack([q_prev, qd_prev, q_rad[i], qd_rad_s[i]])
            rows[i * k : (i + 1) * k] = self._hermite[0] @ ends + self._ff_lead * (
                self._hermite[1] @ ends
            )
            q_prev, qd_prev = q_rad[i], qd_rad_s[i]
        return rows
