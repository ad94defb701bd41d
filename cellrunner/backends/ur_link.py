"""The control script's link to a UR controller (see :mod:`cellrunner.backends.ur`):
RTDEControl started in its own process, its calls translated into cellrunner's errors, and
the process dropped (never left to reconnect by itself) when the link is in doubt."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Generator, Iterator
from typing import Any, TypeVar

from cellrunner.backends.ur_control import ControlLost, ControlProcess
from cellrunner.backends.ur_identity import translate
from cellrunner.backends.ur_state import ROBOT_MODE_RUNNING, safety_of
from cellrunner.errors import BackendError, ConnectionLost, PeerUnreachable
from cellrunner.model.robot_state import Safety

_T = TypeVar("_T")
#: a blocking call that runs bounded steps looks again this often (s)
_POLL_S = 0.01


def drive(steps: Generator[None, None, _T]) -> _T:
    """Run bounded steps to the end, :data:`_POLL_S` apart; their value."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            value: _T = stop.value
            return value
        time.sleep(_POLL_S)


class URControlLink:
    """The control-link part of :class:`~cellrunner.backends.ur.URBackend` (a mixin: it
    works on the backend's settings and control process)."""

    host: str
    rate_hz: float
    connect_timeout_s: float
    tcp_pose: tuple[float, ...] | None
    payload_kg: float | None
    payload_cog_m: tuple[float, float, float]
    _receive: Any
    _control: ControlProcess | None
    _servoing: bool
    _t_cycle: float | None

    def _translate(self, exc: Exception) -> BackendError | PeerUnreachable:
        return translate(self.host, exc)

    def _configure_tool(self) -> None:
        if self.tcp_pose is not None and not self._call("setTcp", list(self.tcp_pose)):
            raise BackendError(
                f"the controller at {self.host} refused setTcp({list(self.tcp_pose)})"
            )
        if self.payload_kg is not None and not self._call(
            "setPayload", self.payload_kg, list(self.payload_cog_m)
        ):
            raise BackendError(
                f"the controller at {self.host} refused setPayload({self.payload_kg})"
            )

    def _call(self, name: str, *args: Any, timeout_s: float | None = None) -> Any:
        """One RTDEControlInterface call in the control process, translated: ur_rtde's
        texts through :meth:`_translate`, a lost process as :class:`ConnectionLost`."""
        control = self._running_control()
        with self._control_errors():
            if timeout_s is None:
                return control.call(name, *args)
            return control.call(name, *args, timeout_s=timeout_s)

    def _call_steps(self, name: str, *args: Any) -> Generator[None, None, Any]:
        """:meth:`_call` as bounded steps: the answer is looked for once per ``next``."""
        control = self._running_control()
        with self._control_errors():
            return (yield from control.call_steps(name, *args))

    def _running_control(self) -> ControlProcess:
        if self._control is None:
            raise BackendError("the control script is not running; recover the arm first")
        return self._control

    @contextlib.contextmanager
    def _control_errors(self) -> Iterator[None]:
        try:
            yield
        except ControlLost as exc:
            self._drop_control()
            raise ConnectionLost(f"lost the control connection to {self.host}: {exc}") from exc
        except RuntimeError as exc:
            error = self._translate(exc)
            if isinstance(error, PeerUnreachable):  # the link broke under the call
                self._drop_control()
                raise ConnectionLost(str(error)) from exc
            raise error from exc

    def _drop_control(self) -> None:
        control, self._control = self._control, None
        self._servoing = False
        self._t_cycle = None
        if control is not None:
            control.close()

    def _arm_ready(self) -> bool:
        return bool(
            safety_of(self._receive.getSafetyStatusBits()) == Safety.NORMAL
            and self._receive.getRobotMode() == ROBOT_MODE_RUNNING
        )

    def _open_control(self) -> None:
        """RTDEControl (in its process) uploads ur_rtde's control script; then the tool
        is configured."""
        drive(self._open_control_steps())

    def _open_control_steps(self) -> Generator[None, None, None]:
        """:meth:`_open_control` as bounded steps (the child starts while we yield)."""
        control = ControlProcess(
            self.host, self.rate_hz, start_timeout_s=self.connect_timeout_s + 10.0
        )
        try:
            yield from control.start_steps()
        except ControlLost as exc:
            raise PeerUnreachable(
                f"cannot reach the robot controller at {self.host}: {exc}"
            ) from exc
        except RuntimeError as exc:
            raise self._translate(exc) from exc
        self._control = control
        self._configure_tool()
