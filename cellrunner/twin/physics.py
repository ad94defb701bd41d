"""What the virtual controller needs from a physics engine, and a kinematic one.

The controller owns time: once per controller period (2 ms e-Series, 8 ms CB3) it calls

1. ``apply_outputs(digital_output_bits)`` -- the IO image the arm's cabinet drives
   (valves, grippers); bit layout as RTDE's ``actual_digital_output_bits``:
   bits 0-7 standard DO0-7, 8-15 configurable CO0-7, 16-17 tool TO0-1;
2. ``step(q_cmd_rad, dt_s)`` -- the joint position set-point of this period (rad) and
   the period (s); the engine moves the arm towards it;
3. ``measure()`` -- a :class:`Measurement`: measured q and qd, the raw wrench at the
   flange (base frame, before any zeroing), digital inputs (same bit layout as
   ``actual_digital_input_bits``) and whether the arm touches something it should not.

``reset(q_rad)`` places the arm. That is the whole contract; the MuJoCo twin implements
the same four methods. Contact makes the controller raise a protective stop, as a real
controller does on a collision.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from cellrunner.model.robots import RobotSpec


@dataclass(frozen=True)
class Measurement:
    """One period's sensor readings (SI units, radians, base frame)."""

    q_rad: np.ndarray
    qd_rad_s: np.ndarray
    wrench_flange: np.ndarray = field(default_factory=lambda: np.zeros(6))  # N, N m
    digital_inputs: int = 0
    contact: bool = False
    analog_inputs: tuple[float, float] = (0.0, 0.0)  # V
    #: what the contact was, when the physics knows (geoms and force), for the log
    contact_what: str = ""


@runtime_checkable
class Physics(Protocol):
    def reset(self, q_rad: np.ndarray) -> None:
        """Place the arm at rest at ``q_rad``."""

    def apply_outputs(self, digital_output_bits: int) -> None:
        """The digital outputs the controller drives this period."""

    def step(self, q_cmd_rad: np.ndarray, dt_s: float) -> None:
        """Advance ``dt_s`` seconds with joint set-point ``q_cmd_rad``."""

    def measure(self) -> Measurement:
        """Readings after the last step."""


class KinematicPhysics:
    """First-order joint tracking with speed limits; IO loop-back; injectable contact.

    ``tau_s`` is the tracking time constant (0: the arm is exactly where it was told one
    period ago). ``loopback`` maps an output bit to an input bit that follows it after
    ``loopback_delay_s`` (a valve and its sensor, e.g. ``{0: 0}``: DO0 -> DI0).
    """

    def __init__(
        self,
        spec: RobotSpec,
        tau_s: float = 0.0,
        loopback: dict[int, int] | None = None,
        loopback_delay_s: float = 0.05,
    ) -> None:
        self.spec = spec
        self.tau_s = tau_s
        self.loopback = dict(loopback or {})
        self.loopback_delay_s = loopback_delay_s
        self._qd_max = np.radians(np.array(spec.joint_speed_max_deg_s, dtype=float))
        self._q = np.zeros(6)
        self._qd = np.zeros(6)
        self._outputs = 0
        self._inputs = 0
        self._pending: dict[int, tuple[bool, float]] = {}  # input bit -> (value, time left)
        self._contact = False
        self._wrench = np.zeros(6)

    def reset(self, q_rad: np.ndarray) -> None:
        self._q = np.array(q_rad, dtype=float)
        self._qd = np.zeros(6)

    def apply_outputs(self, digital_output_bits: int) -> None:
        for out_bit, in_bit in self.loopback.items():
            value = bool(digital_output_bits >> out_bit & 1)
            current = bool(self._inputs >> in_bit & 1)
            pending = self._pending.get(in_bit)
            if value != current and (pending is None or pending[0] != value):
                self._pending[in_bit] = (value, self.loopback_delay_s)
            elif value == current:
                self._pending.pop(in_bit, None)
        self._outputs = digital_output_bits

    def step(self, q_cmd_rad: np.ndarray, dt_s: float) -> None:
        alpha = 1.0 if self.tau_s <= 0 else min(1.0, dt_s / self.tau_s)
        dq = (np.asarray(q_cmd_rad, float) - self._q) * alpha
        limit = self._qd_max * dt_s
        dq = np.clip(dq, -limit, limit)
        self._q = self._q + dq
        self._qd = dq / dt_s
        for bit, (value, left) in list(self._pending.items()):
            left -= dt_s
            if left <= 0:
                self._inputs = self._inputs | (1 << bit) if value else self._inputs & ~(1 << bit)
                del self._pending[bit]
            else:
                self._pending[bit] = (value, left)

    def measure(self) -> Measurement:
        return Measurement(
            q_rad=self._q.copy(),
            qd_rad_s=self._qd.copy(),
            wrench_flange=self._wrench.copy(),
            digital_inputs=self._inputs,
            contact=self._contact,
        )

    # -- fault injection (the control channel uses these when present) --

    def inject_contact(self, active: bool, wrench: np.ndarray | None = None) -> None:
        """Make the arm touch something (``active``) with ``wrench`` at the flange."""
        self._contact = active
        self._wrench = np.zeros(6) if wrench is None else np.asarray(wrench, float)

    def set_wrench(self, wrench: np.ndarray) -> None:
        self._wrench = np.asarray(wrench, float)
