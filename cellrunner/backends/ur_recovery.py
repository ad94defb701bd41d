"""Recovering a UR arm as UR prescribes it (see :mod:`cellrunner.backends.ur`): unlock a
protective stop, power on and release the brakes after an e-stop, re-upload the control
script; every wait bounded, and each also as bounded steps for a control loop that keeps
ticking meanwhile."""

from __future__ import annotations

import time
from collections.abc import Generator
from typing import Any

from cellrunner.backends.ur_identity import translate
from cellrunner.backends.ur_link import URControlLink, drive
from cellrunner.backends.ur_state import ROBOT_MODE_IDLE, ROBOT_MODE_RUNNING, safety_of
from cellrunner.errors import BackendError
from cellrunner.model.robot_state import Safety


class URRecovery(URControlLink):
    """The recovery half of :class:`~cellrunner.backends.ur.URBackend` (a mixin: it
    works on the backend's connections)."""

    _dashboard: Any
    _protective_stop_seen_at: float | None

    def unlock_protective_stop(self) -> None:
        """Close the safety popup, unlock, re-upload the control script.

        Raises :class:`BackendError` with UR's reply when the controller refuses
        (within 5 s of the stop)."""
        if self._dashboard is None:
            raise BackendError("not connected; call connect() first")
        try:
            self._dashboard.closeSafetyPopup()
            self._dashboard.unlockProtectiveStop()
        except RuntimeError as exc:
            text = str(exc).removeprefix("Unlock protective stop failure: ")
            raise BackendError(
                f"the controller refused to unlock the protective stop: {text}"
            ) from exc
        self._protective_stop_seen_at = None
        self._wait_for(
            lambda: safety_of(self._receive.getSafetyStatusBits()) == Safety.NORMAL,
            2.0,
            "the protective stop did not clear",
        )
        self._reupload()

    def recover_from_protective_stop(
        self, unlock_delay_s: float = 5.0, timeout_s: float = 12.0
    ) -> None:
        """Wait until the controller accepts the unlock (``unlock_delay_s`` after the stop
        was first seen), then :meth:`unlock_protective_stop`; bounded by ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        seen = self._protective_stop_seen_at or time.monotonic()
        time.sleep(max(0.0, min(seen + unlock_delay_s + 0.05, deadline) - time.monotonic()))
        while True:
            try:
                self.unlock_protective_stop()
                return
            except BackendError:
                if time.monotonic() + 0.25 > deadline:
                    raise
                time.sleep(0.25)

    def recover_from_estop(self) -> None:
        """After a person released the e-stop (or for an arm found powered off): power
        on, release the brakes, (re)start the control script."""
        drive(self.recover_from_estop_steps())

    def recover_from_estop_steps(self) -> Generator[None, None, None]:
        """:meth:`recover_from_estop` as bounded steps, for a control loop that keeps
        ticking meanwhile: each ``next`` makes at most one dashboard or control call or
        looks at the state once; the waits keep their bounds (power on 30 s, brakes 30 s,
        the control script 5 s) and raise :class:`BackendError` as the blocking call does."""
        if self._dashboard is None or self._receive is None:
            raise BackendError("not connected; call connect() first")
        if safety_of(self._receive.getSafetyStatusBits()) == Safety.EMERGENCY_STOP:
            raise BackendError(
                "the emergency stop is still pressed; a person must release it first"
            )
        dashboard, receive = self._dashboard, self._receive
        try:
            dashboard.closeSafetyPopup()
            yield
            dashboard.powerOn()
            yield from self._until(
                lambda: receive.getRobotMode() in (ROBOT_MODE_IDLE, ROBOT_MODE_RUNNING),
                30.0,
                "the arm did not power on",
            )
            dashboard.brakeRelease()
            yield from self._until(
                lambda: receive.getRobotMode() == ROBOT_MODE_RUNNING,
                30.0,
                "the brakes were not released",
            )
        except RuntimeError as exc:
            raise translate(self.host, exc) from exc
        yield from self._reupload_steps()

    def _reupload(self) -> None:
        drive(self._reupload_steps())

    def _reupload_steps(self) -> Generator[None, None, None]:
        if self._control is None or not self._control.alive:
            self._drop_control()
            yield from self._open_control_steps()
            return
        if not (yield from self._call_steps("reuploadScript")):
            raise BackendError(f"could not re-upload the control script to {self.host}")
        yield from self._until(
            lambda: bool(self._call("isProgramRunning")), 5.0, "the control script did not start"
        )
        self._configure_tool()

    def _wait_for(self, predicate: Any, timeout_s: float, what: str) -> None:
        drive(self._until(predicate, timeout_s, what))

    def _until(self, predicate: Any, timeout_s: float, what: str) -> Generator[None, None, None]:
        """Yield until ``predicate()``; BackendError naming ``what`` after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > deadline:
                raise BackendError(f"{what} within {timeout_s:g} s (controller at {self.host})")
            yield
