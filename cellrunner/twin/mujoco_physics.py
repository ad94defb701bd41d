"""The MuJoCo twin behind the virtual UR controller: the controller's four-method physics
contract (``reset``, ``apply_outputs``, ``step``, ``measure``) over a :class:`SimWorld`.

The controller owns safety: a contact the twin detects is reported as ``contact`` and the
controller raises the protective stop (and decides when it may be unlocked); this
adapter then releases the twin's own stop so the arm can move again once the controller
allows it.
"""

from __future__ import annotations

import contextlib
import threading
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import BackendError
from cellrunner.model.robot_state import Safety

if TYPE_CHECKING:
    from cellrunner.sim.description import TwinDescription
    from cellrunner.twin.physics import Measurement

#: how often (controller periods) the conveyor looks whether its part was taken (sim: feed)
FEED_EVERY_PERIODS = 50

#: RTDE digital bit layout: DO/DI 0-7 standard, 8-15 configurable, 16-17 tool
_BIT_OF_PREFIX = {"D": 0, "C": 8, "T": 16}


def _bit(channel: str) -> int | None:
    if (
        len(channel) < 3
        or channel[0] not in _BIT_OF_PREFIX
        or channel[1] not in "IO"
        or not channel[2:].isdigit()
    ):
        return None
    return _BIT_OF_PREFIX[channel[0]] + int(channel[2:])


class MujocoPhysics:
    """The MuJoCo twin of a cell as the virtual controller's physics."""

    def __init__(self, description: TwinDescription) -> None:
        from cellrunner.sim.world import SimWorld

        self.description = description
        self.world = SimWorld(description)
        self._q_prev: np.ndarray | None = None
        self._contact = False
        self._contact_what = ""
        self._lock = threading.Lock()  # qpos for the camera thread (twin.camera)

    def snapshot_qpos(self) -> np.ndarray:
        """A copy of the whole MuJoCo state's positions (arm, fingers, parts), taken between
        two physics steps."""
        with self._lock:
            return np.asarray(self.world.data.qpos.copy())

    def snapshot_scene(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Positions, mocap bodies (the intruders) and simulated time, taken together
        between two physics steps (what a depth camera sees)."""
        with self._lock:
            d = self.world.data
            return (
                np.asarray(d.qpos.copy()),
                np.asarray(d.mocap_pos.copy()),
                np.asarray(d.mocap_quat.copy()),
                float(self.world.time_s),
            )

    def reset(self, q_rad: np.ndarray) -> None:
        with self._lock:
            self._reset(q_rad)

    def _reset(self, q_rad: np.ndarray) -> None:
        if not self.world.built:
            self.world.build()
        q = np.array(q_rad, dtype=float)
        self.world.place_arm(q)
        self._q_prev = q

    def encoder_ticks(self, index: int) -> int | None:
        """The ticks of the belt encoder wired to pulse decoder ``index`` (see
        :mod:`cellrunner.twin.pulse_decoder`); None when none is, or before the world is
        built."""
        belts = self.world.belts if self.world.built else None
        return None if belts is None else belts.encoder_ticks(index)

    def inject_fault(self, fault: str) -> None:
        """grip_miss or part_slip, made to happen in the MuJoCo twin (as dry-run does)."""
        self.world.inject_fault(fault)

    def apply_outputs(self, digital_output_bits: int) -> None:
        for channel in self.world.outputs:
            bit = _bit(channel)
            if bit is not None:
                value = bool(digital_output_bits >> bit & 1)
                if self.world.outputs[channel] != value:
                    self.world.set_output(channel, value)

    def step(self, q_cmd_rad: np.ndarray, dt_s: float) -> None:
        with self._lock:
            self._step(q_cmd_rad, dt_s)

    def _step(self, q_cmd_rad: np.ndarray, dt_s: float) -> None:
        world = self.world
        q_cmd = np.asarray(q_cmd_rad, float)
        qd = (q_cmd - self._q_prev) / dt_s if self._q_prev is not None else np.zeros(6)
        self._q_prev = q_cmd
        if world.safety is Safety.PROTECTIVE_STOP:
            # the controller decides when a stop ends (its 5 s rule); the twin follows, unless
            # the twin's own 5 s have not passed yet either
            with contextlib.suppress(BackendError):
                world.unlock_protective_stop()
        if world.safety is Safety.NORMAL and not world.stopping:
            world.command(q_cmd, qd)
        world.step_period()
        if world.feeder is not None and world.periods % FEED_EVERY_PERIODS == 0:
            world.feeder.update()  # the conveyor brings the next part once one was taken
        stopped = world.safety is Safety.PROTECTIVE_STOP
        if stopped != self._contact:  # a stop begins or ends: the contact it met, if any
            hit = world.last_contact
            self._contact_what = (
                f"{hit.geoms[0]} against {hit.geoms[1]}, {hit.force_N:.0f} N at {hit.time_s:.3f} s"
                if stopped and hit is not None and hit.time_s == world.stop_time_s
                else ""
            )
        self._contact = stopped

    def measure(self) -> Measurement:
        from cellrunner.twin.physics import Measurement

        state = self.world.measure()
        bits = 0
        for channel, value in state.inputs.items():
            bit = _bit(channel)
            if bit is not None and value:
                bits |= 1 << bit
        return Measurement(
            q_rad=state.q_rad,
            qd_rad_s=state.qd_rad_s,
            wrench_flange=np.asarray(state.wrench_N),
            digital_inputs=bits,
            contact=self._contact,
            contact_what=self._contact_what,
        )
