"""How the twin controller stops and starts again: protective stops (injected, or a
collision that backs off), the emergency stop (a category 1 stop, then power off) and
their recovery, and the stop ramps that bring the set-point to standstill. Part of
:class:`.world.SimWorld` (its ``stops``); the safety state it changes is the world's."""

from __future__ import annotations

from typing import Any

from cellrunner.errors import BackendError
from cellrunner.model.robot_state import Safety
from cellrunner.sim.safety import (
    COLLISION_BACKOFF_S,
    STOP_DECEL_RAD_S2,
    UNLOCK_DELAY_S,
    StopRamp,
    StopReason,
)
from cellrunner.sim.servo import ZERO6 as _ZERO6


class StopControl:
    """The stops of one built SimWorld."""

    def __init__(self, world: Any) -> None:
        self.world = world

    def unlock_protective_stop(self) -> None:
        w = self.world
        if w.safety is Safety.NORMAL:
            return
        if w.safety is not Safety.PROTECTIVE_STOP:
            raise BackendError(f"cannot unlock a protective stop in state {w.safety.value}")
        assert w.stop_time_s is not None
        elapsed = w.time_s - w.stop_time_s
        if elapsed < UNLOCK_DELAY_S:
            raise BackendError(
                f"protective stop cannot be unlocked yet: {elapsed:.2f} s since the stop, "
                f"the controller needs {UNLOCK_DELAY_S:.0f} s"
            )
        self.resume()

    def press_estop(self) -> None:
        """A person presses the emergency stop: category 1 stop, then power off."""
        w = self.world
        w.estop_pressed = True
        if w.safety is not Safety.EMERGENCY_STOP:
            w.safety = Safety.EMERGENCY_STOP
            w.stop_time_s = w.time_s
            self.begin_stop(STOP_DECEL_RAD_S2)

    def recover_from_estop(self) -> None:
        w = self.world
        if w.safety is not Safety.EMERGENCY_STOP:
            return
        if w.estop_pressed:
            raise BackendError("emergency stop is still pressed; a person must release it first")
        w.powered = True
        self.resume()

    def raise_protective_stop(self, reason: StopReason = StopReason.INJECTED) -> None:
        w = self.world
        if w.safety is not Safety.NORMAL:
            return
        w.safety = Safety.PROTECTIVE_STOP
        w.stop_time_s = w.time_s
        if reason is StopReason.CONTACT:
            # A collision: hold where the arm was just before (backing off 20 ms of the
            # motion, as UR arms back off) rather than ramp on into the obstacle.
            w._stop = None
            q, qd = w.data.qpos[w.ids.qpos], w.data.qvel[w.ids.dof]
            w.q_ref = w._q_prev_ref = q - COLLISION_BACKOFF_S * qd
            w.qd_ref = w._qd_prev_ref = _ZERO6
        else:
            self.begin_stop(STOP_DECEL_RAD_S2)

    def begin_stop(self, decel_rad_s2: float) -> None:
        w = self.world
        qd0 = w.qd_ref.copy() if w._stop is None else w._stop.speed(w.time_s)
        w._stop = StopRamp.from_speed(w.time_s, qd0, decel_rad_s2)

    def resume(self) -> None:
        w = self.world
        w.safety = Safety.NORMAL
        w.stop_time_s = None
        w._stop = None
        w.q_ref = w._q_prev_ref = w.data.qpos[w.ids.qpos].copy()
        w.qd_ref = w._qd_prev_ref = _ZERO6
