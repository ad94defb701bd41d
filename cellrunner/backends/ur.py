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

ur_rtde's exceptions (``RuntimeError``/``logic_error`` with text) are translated here.
"""

from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Generator, Iterator
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from cellrunner.backends.ur_control import ControlLost, ControlProcess
from cellrunner.backends.ur_io import IoConnectionLost, RtdeOutputWriter
from cellrunner.backends.ur_probe import controller_version, generation_of
from cellrunner.backends.ur_state import RtdeStateReader
from cellrunner.errors import (  # re-exported
    BackendError,
    ConnectionLost,
    ControllerMismatch,
    PeerUnreachable,
    RemoteControlOff,
    SafetyStop,
)
from cellrunner.model.gripper import ROBOTIQ_CLOSE, ROBOTIQ_OBJECT
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.model.robots import RobotSpec
from cellrunner.model.trajectory import ApprovedTrajectory

_T = TypeVar("_T")
#: a blocking call that runs bounded steps looks again this often (s)
_POLL_S = 0.01


def _drive(steps: Generator[None, None, _T]) -> _T:
    """Run bounded steps to the end, :data:`_POLL_S` apart; their value."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            value: _T = stop.value
            return value
        time.sleep(_POLL_S)


if TYPE_CHECKING:
    from cellrunner.backends.robotiq import RobotiqClient

RECEIVE_VARIABLES = [
    "timestamp",
    "actual_q",
    "actual_qd",
    "target_q",
    "actual_TCP_force",
    "robot_mode",
    "safety_mode",
    "robot_status_bits",
    "safety_status_bits",
    "runtime_state",
    "actual_digital_input_bits",
    "actual_digital_output_bits",
    "standard_analog_input0",
    "standard_analog_input1",
    "standard_analog_output0",
    "standard_analog_output1",
]
_ROBOT_MODE_RUNNING = 7
_ROBOT_MODE_IDLE = 5
_CHANNELS = "DO0-7, CO0-7, TO0-1, AO0-1"


#: ur_rtde's RuntimeError texts -> (cellrunner error, message); the first marker found wins
UR_RTDE_ERRORS: tuple[tuple[str, type[BackendError] | type[PeerUnreachable], str], ...] = (
    ("Could not connect", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("Timeout connecting", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("End of file", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("connection", PeerUnreachable, "cannot reach the robot controller at {host}: {text}"),
    ("remote control", RemoteControlOff, "the controller at {host}: {text}"),
)


def _model_family(name: str) -> str:
    """``ur5e`` / ``UR5e`` / ``UR5`` -> ``UR5``."""
    return name.strip().upper().removesuffix("E")


def _safety_of(bits: int) -> Safety:
    if bits & (1 << 5 | 1 << 6 | 1 << 7):
        return Safety.EMERGENCY_STOP
    if bits & (1 << 8 | 1 << 9):
        return Safety.FAULT
    if bits & (1 << 2 | 1 << 4):
        return Safety.PROTECTIVE_STOP
    return Safety.NORMAL


def _serial_number(dashboard: Any) -> str:
    """The controller's serial number, "" when the dashboard does not give one (an old
    controller, an answer that is no number)."""
    try:
        text = str(dashboard.getSerialNumber()).strip()
    except RuntimeError:
        return ""
    return text if text.isalnum() else ""


def _channel(name: str) -> tuple[str, int]:
    kind, index = name[:2].upper(), name[2:]
    limits = {"DO": 8, "CO": 8, "TO": 2, "AO": 2, "DI": 8, "CI": 8, "TI": 2, "AI": 2}
    if kind not in limits or not index.isdigit() or int(index) >= limits[kind]:
        raise BackendError(f"unknown output channel {name!r}; valid: {_CHANNELS}")
    return kind, int(index)


class URBackend:
    """A UR arm through ur_rtde; see the module docstring for the lifecycle."""

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
        versions = controller_version(self.host, self.connect_timeout_s)
        generation = generation_of(versions)
        version_text = ".".join(str(v) for v in versions)
        if generation != self.spec.generation:
            raise ControllerMismatch(
                f"the controller at {self.host} is {generation} (PolyScope {version_text}) "
                f"but the cell's robot {self.spec.name} is {self.spec.generation}"
            )
        self.controller_versions = versions
        import dashboard_client

        try:
            self._dashboard = dashboard_client.DashboardClient(self.host)
            self._dashboard.connect(int(self.connect_timeout_s * 1000))
            self.robot_model = self._dashboard.getRobotModel().strip()
            self.serial_number = _serial_number(self._dashboard)
            expected = _model_family(self.spec.name)
            # the dashboard answers "UR5" for a UR5 and a UR5e alike (the generation was
            # checked above); a reply that names no model is not held against the robot
            reported = _model_family(self.robot_model)
            if re.fullmatch(r"UR\d+", reported) and reported != expected:
                raise ControllerMismatch(
                    f"the controller at {self.host} drives a {self.robot_model} "
                    f"but the cell's robot is {self.spec.name} ({expected})"
                )
            if (
                self.require_remote_control
                and versions[0] == 5
                and versions[1] >= 6
                and not self._dashboard.isInRemoteControl()
            ):
                raise RemoteControlOff(
                    f"the controller at {self.host} is in local control; "
                    "switch the teach pendant to Remote Control"
                )
            self._receive = RtdeStateReader(
                self.host, self.rate_hz, RECEIVE_VARIABLES, timeout_s=self.connect_timeout_s
            )
            self._receive.connect()
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
        return (
            _safety_of(self._receive.getSafetyStatusBits()) == Safety.NORMAL
            and self._receive.getRobotMode() == _ROBOT_MODE_RUNNING
        )

    def _open_control(self) -> None:
        """RTDEControl (in its process) uploads ur_rtde's control script; then the tool
        is configured."""
        _drive(self._open_control_steps())

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

    def _translate(self, exc: Exception) -> BackendError | PeerUnreachable:
        """ur_rtde's ``RuntimeError`` (or a socket's ``OSError``) as cellrunner's error,
        through :data:`UR_RTDE_ERRORS`."""
        text = str(exc)
        if isinstance(exc, OSError):
            return PeerUnreachable(f"cannot reach the robot controller at {self.host}: {text}")
        for marker, error, template in UR_RTDE_ERRORS:
            if marker in text:
                return error(template.format(host=self.host, text=text))
        return BackendError(f"ur_rtde: {text}")

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
        receive = self._receive
        if receive is None or not receive.isConnected():
            return RobotState(
                0.0, np.zeros(6), np.zeros(6), np.zeros(6), Safety.DISCONNECTED, powered=False
            )
        safety = _safety_of(receive.getSafetyStatusBits())
        if self._control is not None and not self._control.alive:
            safety = Safety.DISCONNECTED
        inputs_bits, output_bits = (
            receive.getActualDigitalInputBits(),
            receive.getActualDigitalOutputBits(),
        )
        inputs: dict[str, float | bool] = {}
        outputs: dict[str, float | bool] = {}
        for prefix, bits, target in (("I", inputs_bits, inputs), ("O", output_bits, outputs)):
            for i in range(8):
                target[f"D{prefix}{i}"] = bool(bits >> i & 1)
                target[f"C{prefix}{i}"] = bool(bits >> (8 + i) & 1)
            for i in range(2):
                target[f"T{prefix}{i}"] = bool(bits >> (16 + i) & 1)
        inputs["AI0"], inputs["AI1"] = (
            receive.getStandardAnalogInput0(),
            receive.getStandardAnalogInput1(),
        )
        if self._robotiq is not None:
            inputs[ROBOTIQ_OBJECT] = self._robotiq.object_detected
        outputs["AO0"], outputs["AO1"] = (
            receive.getStandardAnalogOutput0(),
            receive.getStandardAnalogOutput1(),
        )
        return RobotState(
            time_s=receive.getTimestamp(),
            q_rad=np.array(receive.getActualQ()),
            qd_rad_s=np.array(receive.getActualQd()),
            wrench_N=np.array(receive.getActualTCPForce()),
            safety=safety,
            inputs=inputs,
            outputs=outputs,
            powered=bool(receive.getRobotStatus() & 1),
            brakes_released=receive.getRobotMode() == _ROBOT_MODE_RUNNING,
        )

    # ------------------------------------------------------------------ streaming

    def _check_link_and_safety(self) -> None:
        if self._receive is None:
            raise BackendError("not connected; call connect() first")
        if not self._link_up():
            self._drop_control()  # never let ur_rtde reconnect by itself: it races
            raise ConnectionLost(f"lost the connection to the controller at {self.host}")
        safety = _safety_of(self._receive.getSafetyStatusBits())
        if safety != Safety.NORMAL:
            if safety == Safety.PROTECTIVE_STOP and self._protective_stop_seen_at is None:
                self._protective_stop_seen_at = time.monotonic()
            self._servoing = False
            self._t_cycle = None
            raise SafetyStop(
                f"the controller at {self.host} stopped the arm: {safety.value}", safety
            )
        if self._control is None:
            if self._receive.getRobotMode() != _ROBOT_MODE_RUNNING:
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
        kind, index = _channel(channel)
        io = self._io
        if io is None:
            raise BackendError("not connected; call connect() first")
        try:
            if kind in ("DO", "CO", "TO"):
                io.set_digital(kind, index, bool(value))
            elif kind == "AO":
                if not 0.0 <= float(value) <= 1.0:
                    raise BackendError(
                        f"{channel}: {value} is not a fraction of the range in [0, 1]"
                    )
                io.set_analog_voltage(index, float(value))
            else:
                raise BackendError(f"{channel} is an input; valid outputs: {_CHANNELS}")
        except IoConnectionLost as exc:
            raise ConnectionLost(str(exc)) from exc

    def zero_ft_sensor(self) -> None:
        if self.spec.generation != "e-Series":
            raise BackendError(
                f"{self.spec.name} (CB3) has no built-in force/torque sensor to zero"
            )
        self._check_link_and_safety()
        if not self._call("zeroFtSensor"):
            raise BackendError(f"the controller at {self.host} refused zeroFtSensor")

    # ------------------------------------------------------------------ recovery

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
            lambda: _safety_of(self._receive.getSafetyStatusBits()) == Safety.NORMAL,
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
        _drive(self.recover_from_estop_steps())

    def recover_from_estop_steps(self) -> Generator[None, None, None]:
        """:meth:`recover_from_estop` as bounded steps, for a control loop that keeps
        ticking meanwhile: each ``next`` makes at most one dashboard or control call or
        looks at the state once; the waits keep their bounds (power on 30 s, brakes 30 s,
        the control script 5 s) and raise :class:`BackendError` as the blocking call does."""
        if self._dashboard is None or self._receive is None:
            raise BackendError("not connected; call connect() first")
        if _safety_of(self._receive.getSafetyStatusBits()) == Safety.EMERGENCY_STOP:
            raise BackendError(
                "the emergency stop is still pressed; a person must release it first"
            )
        dashboard, receive = self._dashboard, self._receive
        try:
            dashboard.closeSafetyPopup()
            yield
            dashboard.powerOn()
            yield from self._until(
                lambda: receive.getRobotMode() in (_ROBOT_MODE_IDLE, _ROBOT_MODE_RUNNING),
                30.0,
                "the arm did not power on",
            )
            dashboard.brakeRelease()
            yield from self._until(
                lambda: receive.getRobotMode() == _ROBOT_MODE_RUNNING,
                30.0,
                "the brakes were not released",
            )
        except RuntimeError as exc:
            raise self._translate(exc) from exc
        yield from self._reupload_steps()

    def _reupload(self) -> None:
        _drive(self._reupload_steps())

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
        _drive(self._until(predicate, timeout_s, what))

    def _until(self, predicate: Any, timeout_s: float, what: str) -> Generator[None, None, None]:
        """Yield until ``predicate()``; BackendError naming ``what`` after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > deadline:
                raise BackendError(f"{what} within {timeout_s:g} s (controller at {self.host})")
            yield
