"""The ``ur`` backend: a Universal Robots controller through ur_rtde.

Lifecycle (``RobotBackend``): construct (no I/O) -> :meth:`URBackend.connect` -> cycles
of ``servo(trajectory, i)`` + ``wait_period()`` -> :meth:`URBackend.close`.

``connect`` first probes the controller over RTDE (bounded, :mod:`ur_probe`) and asks the
dashboard for its model and remote-control state; it refuses a controller whose
generation or model differs from the cell's (:class:`ControllerMismatch`) and one in
local control (:class:`RemoteControlOff`). Then it opens the state stream (every
controller period, :mod:`ur_state`), RTDEControl (uploads ur_rtde's control script, in
its own process: :mod:`ur_control`) and the outputs (:mod:`ur_io`).

Streaming is ``servoJ`` at the controller rate (500 Hz e-Series, 125 Hz CB3), paced on
a fixed monotonic schedule; every ``servo`` call first checks the safety bits of the
latest state and raises :class:`SafetyStop` on a protective or emergency stop,
:class:`ConnectionLost` when a connection dropped.

Threading: every ur_rtde object is touched from the caller's thread only (the control
thread). RTDEControlInterface runs in a child process (:mod:`ur_control`), because its
own reconnect races inside the library and crashes the process that holds it; the child
is killed when the link drops and a reconnect builds a new one.

Recovery, as UR prescribes it:

- protective stop: :meth:`unlock_protective_stop` closes the safety popup and unlocks
  (the controller refuses for 5 s after the stop: :class:`BackendError` carrying UR's
  text), then re-uploads the control script; :meth:`recover_from_protective_stop` waits
  for the 5 s itself (bounded);
- e-stop: after a person released it, :meth:`recover_from_estop` powers on, releases the
  brakes and re-uploads the control script;
- connection loss: :meth:`reconnect` retries with exponential backoff for a bounded
  time, then raises :class:`PeerUnreachable` (result code 102 for the engine).

ur_rtde's exceptions (``RuntimeError``/``logic_error`` with text) are translated here
(:mod:`ur_identity`); recovery lives in :mod:`ur_recovery`, the state in :mod:`ur_state`,
the outputs in :mod:`ur_io`.
"""

from __future__ import annotations

import contextlib
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.backends.ur_control import ControlProcess
from cellrunner.backends.ur_conveyor import UREncoders
from cellrunner.backends.ur_identity import UR_RTDE_ERRORS, check_dashboard
from cellrunner.backends.ur_io import RtdeOutputWriter, write_output
from cellrunner.backends.ur_probe import controller_version, generation_of
from cellrunner.backends.ur_recovery import URRecovery
from cellrunner.backends.ur_state import (
    RECEIVE_VARIABLES,
    ROBOT_MODE_RUNNING,
    RtdeStateReader,
    robot_state_of,
    safety_of,
)
from cellrunner.errors import (  # re-exported
    BackendError,
    ConnectionLost,
    ControllerMismatch,
    PeerUnreachable,
    RemoteControlOff,
    SafetyStop,
)
from cellrunner.model.gripper import ROBOTIQ_CLOSE
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.model.robots import RobotSpec
from cellrunner.model.trajectory import ApprovedTrajectory

if TYPE_CHECKING:
    from collections.abc import Mapping

    from cellrunner.backends.robotiq import RobotiqClient
    from cellrunner.model.conveyor import Conveyor

__all__ = [
    "RECEIVE_VARIABLES",
    "UR_RTDE_ERRORS",
    "BackendError",
    "ConnectionLost",
    "ControllerMismatch",
    "PeerUnreachable",
    "RemoteControlOff",
    "SafetyStop",
    "URBackend",
]


def _same_generation(host: str, spec: RobotSpec, timeout_s: float) -> tuple[int, ...]:
    """The controller's PolyScope version, refused when it is not the cell's robot's
    generation (e-Series or CB3)."""
    versions = controller_version(host, timeout_s)
    generation = generation_of(versions)
    if generation != spec.generation:
        version_text = ".".join(str(v) for v in versions)
        raise ControllerMismatch(
            f"the controller at {host} is {generation} (PolyScope {version_text}) "
            f"but the cell's robot {spec.name} is {spec.generation}"
        )
    return versions


class URBackend(URRecovery):
    """A UR arm through ur_rtde; see the module docstring for the lifecycle."""

    #: the controller's time runs on while the engine works between two periods (a
    #: tracked stretch is made off the control thread: execution.belt_tracking)
    clock_runs_on = True

    def __init__(
        self,
        host: str,
        spec: RobotSpec,
        *,
        servo_lookahead_s: float = 0.03,
        servo_gain: float = 1000.0,
        connect_timeout_s: float = 3.0,
        reconnect_timeout_s: float = 10.0,
        require_remote_control: bool = True,
        robotiq_port: int | None = None,
        tcp_pose: tuple[float, ...] | None = None,
        payload_kg: float | None = None,
        payload_cog_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
        conveyors: Mapping[str, Conveyor] | None = None,
    ) -> None:
        self.host = host
        self.spec = spec
        self.rate_hz = spec.rate_hz
        self.period_s = 1.0 / spec.rate_hz
        self.servo_lookahead_s = servo_lookahead_s
        self.servo_gain = servo_gain
        self.connect_timeout_s = connect_timeout_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.require_remote_control = require_remote_control
        self.robotiq_port = robotiq_port  # a Robotiq 2F on this controller's socket, or None
        self._robotiq: RobotiqClient | None = None
        # set on the controller at every connect: TCP as a UR pose in the flange frame
        # (m, rotation vector rad), payload mass (kg) and centre of gravity (m, flange)
        self.tcp_pose = tcp_pose
        self.payload_kg = payload_kg
        self.payload_cog_m = payload_cog_m
        self.controller_versions: tuple[int, ...] | None = None
        self.robot_model = ""
        #: the controller's serial number (its dashboard's), "" until connected
        self.serial_number = ""
        self._dashboard: Any = None
        self._receive: Any = None
        self._control: ControlProcess | None = None
        self._io: Any = None
        self._t_cycle: float | None = None  # monotonic time of the current period's start
        self._servoing = False
        self._protective_stop_seen_at: float | None = None
        #: the cell's conveyor encoders (the pulse decoder's count on the state stream)
        self._encoders = UREncoders(conveyors or {})

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> None:
        """Probe, check identity and remote control, open the ur_rtde interfaces.

        An arm that is not ready (powered off, brakes on, protective or emergency stop)
        does not fail ``connect``: the state shows it (``read_state``) and the control
        script is uploaded once :meth:`unlock_protective_stop` / :meth:`recover_from_estop`
        (which also powers up a powered-off arm) made the arm ready."""
        if self.robotiq_port is not None and self._robotiq is None:
            from cellrunner.backends.robotiq import RobotiqClient

            self._robotiq = RobotiqClient(self.host, self.robotiq_port, self.connect_timeout_s)
            self._robotiq.connect()
        self._close_quietly()
        versions = self.controller_versions = _same_generation(
            self.host, self.spec, self.connect_timeout_s
        )
        import dashboard_client

        try:
            self._dashboard = dashboard_client.DashboardClient(self.host)
            self._dashboard.connect(int(self.connect_timeout_s * 1000))
            self.robot_model, self.serial_number = check_dashboard(
                self._dashboard,
                self.host,
                self.spec,
                versions,
                require_remote_control=self.require_remote_control,
            )
            self._receive = RtdeStateReader(
                self.host,
                self.rate_hz,
                RECEIVE_VARIABLES + self._encoders.receive_variables(),
                timeout_s=self.connect_timeout_s,
            )
            self._receive.connect()
            self._encoders.configure(self.host, self.connect_timeout_s)
            self._io = RtdeOutputWriter(self.host, timeout_s=self.connect_timeout_s)
            self._io.connect()
            if self._arm_ready():
                self._open_control()
        except BackendError:
            self._close_quietly()
            raise
        except (RuntimeError, OSError) as exc:
            self._close_quietly()
            raise self._translate(exc) from exc

    def set_tool(
        self, T_flange_tcp: np.ndarray, payload_kg: float, payload_cog_m: tuple[float, float, float]
    ) -> None:
        from cellrunner.model.geometry import tcp_pose_of

        self.tcp_pose = tcp_pose_of(T_flange_tcp)
        cx, cy, cz = payload_cog_m  # a list from a caller becomes the tuple kept
        self.payload_kg, self.payload_cog_m = payload_kg, (cx, cy, cz)
        if self._control is None:
            return  # set at the next connect
        if self._servoing:  # standing still at a tool change; leave servo mode first
            self._call("servoStop", 4.0)
            self._servoing, self._t_cycle = False, None
        self._configure_tool()

    def close(self) -> None:
        """Stop motion and release every connection; idempotent."""
        if self._control is not None and self._link_up():
            try:  # (on a broken link ur_rtde would try to reconnect inside these calls)
                if self._servoing and self._call("isProgramRunning", timeout_s=1.0):
                    self._call("servoStop", 4.0, timeout_s=1.0)
                self._call("stopScript", timeout_s=1.0)
            except BackendError:
                pass
        self._servoing = False
        self._t_cycle = None
        if self._robotiq is not None:
            self._robotiq.close()
            self._robotiq = None
        self._close_quietly()

    def _close_quietly(self) -> None:
        if self._io is not None:
            self._io.close()
            self._io = None
        self._drop_control()
        receive, self._receive = self._receive, None
        if receive is not None:
            with contextlib.suppress(RuntimeError):
                receive.disconnect()
        if self._dashboard is not None:
            with contextlib.suppress(RuntimeError):
                self._dashboard.disconnect()
            self._dashboard = None

    def reconnect(self, timeout_s: float | None = None) -> None:
        """Reopen every connection, retrying with exponential backoff (0.2 s doubling to
        2 s) for at most ``timeout_s`` (default ``reconnect_timeout_s``); raises
        :class:`PeerUnreachable` if the controller does not come back."""
        deadline = time.monotonic() + (self.reconnect_timeout_s if timeout_s is None else timeout_s)
        self._servoing = False
        self._close_quietly()
        delay, last_error = 0.2, None
        while True:
            try:
                self.connect()
                return
            except (PeerUnreachable, ConnectionLost) as exc:
                last_error = exc
            if time.monotonic() + delay > deadline:
                raise PeerUnreachable(
                    f"the robot controller at {self.host} did not come back: {last_error}"
                ) from last_error
            time.sleep(delay)
            delay = min(2.0, delay * 2)

    # ------------------------------------------------------------------ state

    def job_started(self) -> None:
        """Nothing to do on the arm: the world around it runs on its own."""

    @property
    def connected(self) -> bool:
        return self._link_up() and self._control is not None and self._dashboard is not None

    def _link_up(self) -> bool:
        """The state stream is live and the control process (when there is one) runs."""
        receive = self._receive
        if receive is None or not receive.isConnected():
            return False
        return self._control is None or self._control.alive

    def read_state(self) -> RobotState:
        control_lost = self._control is not None and not self._control.alive
        robotiq = self._robotiq
        return robot_state_of(
            self._receive,
            control_lost=control_lost,
            robotiq_object=None if robotiq is None else robotiq.object_detected,
        )

    def conveyor_travel_m(self, name: str) -> float | None:
        """How far conveyor ``name`` has travelled, m, as its encoder reads it in the
        latest state (:mod:`ur_conveyor`); None when this backend cannot measure it."""
        receive = self._receive
        if receive is None or not receive.isConnected():
            return None
        return self._encoders.travel_m(name, receive, receive.getTimestamp())

    # ------------------------------------------------------------------ streaming

    def _check_link_and_safety(self) -> None:
        if self._receive is None:
            raise BackendError("not connected; call connect() first")
        if not self._link_up():
            self._drop_control()  # never let ur_rtde reconnect by itself: it races
            raise ConnectionLost(f"lost the connection to the controller at {self.host}")
        safety = safety_of(self._receive.getSafetyStatusBits())
        if safety != Safety.NORMAL:
            if safety == Safety.PROTECTIVE_STOP and self._protective_stop_seen_at is None:
                self._protective_stop_seen_at = time.monotonic()
            self._servoing = False
            self._t_cycle = None
            raise SafetyStop(
                f"the controller at {self.host} stopped the arm: {safety.value}", safety
            )
        if self._control is None:
            if self._receive.getRobotMode() != ROBOT_MODE_RUNNING:
                raise BackendError(
                    f"the arm at {self.host} is not ready (robot mode {self._receive.getRobotMode()}); "
                    "power it on and release the brakes (recover_from_estop)"
                )
            self._open_control()

    def servo(self, trajectory: ApprovedTrajectory, index: int) -> None:
        if not isinstance(trajectory, ApprovedTrajectory) or not trajectory.is_sealed:
            raise BackendError(
                "refusing a trajectory that planning did not approve (seal missing or broken)"
            )
        if abs(trajectory.trajectory.rate_hz - self.rate_hz) > 1e-9:
            raise BackendError(
                f"trajectory sampled at {trajectory.trajectory.rate_hz} Hz; "
                f"the {self.spec.generation} controller runs at {self.rate_hz} Hz"
            )
        self._check_link_and_safety()
        if self._t_cycle is None:  # first set-point of a stream: the schedule starts now
            self._t_cycle = time.monotonic()
        q = [float(x) for x in trajectory.trajectory.q_rad[index]]
        ok = self._call(
            "servoJ", q, 0.0, 0.0, self.period_s, self.servo_lookahead_s, self.servo_gain
        )
        if not ok:
            # the control and receive connections see a stop in different packages: give
            # the safety bits a few periods to arrive so the caller learns why
            deadline = time.monotonic() + 0.05
            while time.monotonic() < deadline:
                self._check_link_and_safety()
                time.sleep(self.period_s)
            self._t_cycle = None
            raise BackendError(
                f"the controller at {self.host} refused servoJ (control script not running)"
            )
        self._servoing = True

    def wait_period(self) -> None:
        """Sleep until the next period of a fixed schedule (start + k * period), so time
        spent between ``wait_period`` and ``servo`` does not stretch the stream."""
        if self._t_cycle is None:
            time.sleep(self.period_s)
            return
        self._t_cycle += self.period_s
        delay = self._t_cycle - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        elif delay < -self.period_s:  # fell more than a period behind: restart the schedule
            self._t_cycle = time.monotonic()

    def stop_motion(self) -> None:
        if self._control is None or not self._link_up():
            return  # no link: the controller stops the arm itself
        try:
            if self._call("isProgramRunning"):
                if self._servoing:
                    self._call("servoStop", 4.0)
                else:
                    self._call("stopJ", 2.0)
        finally:
            self._servoing = False
            self._t_cycle = None

    # ------------------------------------------------------------------ IO and sensors

    def set_output(self, channel: str, value: bool | float) -> None:
        if channel == ROBOTIQ_CLOSE and self._robotiq is not None:
            self._robotiq.move(bool(value))
            return
        write_output(self._io, channel, value)

    def zero_ft_sensor(self) -> None:
        if self.spec.generation != "e-Series":
            raise BackendError(
                f"{self.spec.name} (CB3) has no built-in force/torque sensor to zero"
            )
        self._check_link_and_safety()
        if not self._call("zeroFtSensor"):
            raise BackendError(f"the controller at {self.host} refused zeroFtSensor")
