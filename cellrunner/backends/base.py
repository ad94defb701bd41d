"""The robot backend Protocol: the one surface the execution engine drives.

Lifecycle: construct (no I/O) -> ``connect()`` -> cycles -> ``close()``.
The engine streams an :class:`ApprovedTrajectory` itself, one set-point per controller
cycle: ``servo(trajectory, i)`` then ``wait_period()`` (the sim backend advances its
physics by one period there; the UR backend waits for the controller's next cycle, as
ur_rtde's initPeriod/waitPeriod do). Nothing here blocks longer than one period except
``connect`` and the recovery actions, which document their own bounds.

Beyond :class:`RobotBackend`, a backend may offer small capabilities the engine asks for
with ``isinstance`` (each Protocol is runtime-checkable): :class:`FeedsParts` (an infeed
it drives itself), :class:`CameraImages` (the cell cameras' pictures) and
:class:`RendersDepth` (the depth cameras of the watched zone). The in-process twin
(``sim``) has all three; the arm (``ur``) has none: its pictures and depth images come
from the cameras themselves.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, Protocol, runtime_checkable

import numpy as np

from cellrunner.errors import BackendError as BackendError  # re-exported: backends raise it
from cellrunner.model.robot_state import RobotState as RobotState  # re-exported
from cellrunner.model.robot_state import Safety as Safety  # re-exported
from cellrunner.model.trajectory import ApprovedTrajectory


@runtime_checkable
class RobotBackend(Protocol):
    rate_hz: float
    #: how long (s) the engine keeps trying to reconnect a lost robot link before the job
    #: ends with 102; 0: a single attempt (a backend with nothing to wait for)
    reconnect_timeout_s: float

    def connect(self) -> None:
        """Open connections / build the model; raise PeerUnreachable when unreachable."""

    def close(self) -> None:
        """Stop motion if any and release every resource; idempotent."""

    def read_state(self) -> RobotState:
        """The latest measured state (non-blocking)."""

    def servo(self, trajectory: ApprovedTrajectory, index: int) -> None:
        """Command set-point ``index`` of an approved, sealed trajectory (servoJ)."""

    def wait_period(self) -> None:
        """Block until the next controller cycle (sim: advance physics one period)."""

    def stop_motion(self) -> None:
        """Decelerate to standstill within the controller's limits (stopJ)."""

    def set_output(self, channel: str, value: bool | float) -> None:
        """Set a digital/tool/analog output by channel name (``DO0``, ``TO1``, ``AO0``)."""

    def zero_ft_sensor(self) -> None:
        """Zero the wrist force/torque reading (e-Series zeroFtSensor)."""

    def set_tool(
        self, T_flange_tcp: np.ndarray, payload_kg: float, payload_cog_m: tuple[float, float, float]
    ) -> None:
        """A tool change: the controller's TCP (flange frame) and payload (kg, centre of
        gravity in m, flange frame), kept for every reconnect (setTcp, setPayload)."""

    def unlock_protective_stop(self) -> None:
        """Close the popup and unlock a protective stop; raises BackendError when the
        controller refuses (before its 5 s unlock delay)."""

    def recover_from_estop(self) -> None:
        """After a person released the e-stop: power on, release brakes, re-arm."""

    def recover_from_estop_steps(self) -> Generator[None, None, None]:
        """:meth:`recover_from_estop` as bounded steps, each ``next`` short (no wait), so
        the control loop keeps ticking while the arm powers up; raises as it does."""

    def reconnect(self, timeout_s: float | None = None) -> None:
        """After ``read_state().safety`` is DISCONNECTED (or a call raised): reopen the
        connections, retrying with backoff for at most ``timeout_s``; raise
        PeerUnreachable if the robot does not come back (result code 102). The sim
        backend has nothing to reconnect and returns at once."""

    def job_started(self) -> None:
        """A job starts now (after it was planned): the twin's scheduled intruders count
        from here. Nothing to do on the arm."""


@runtime_checkable
class ExplainsStops(Protocol):
    """A backend that knows what raised a protective stop (the twin's contacts)."""

    def stop_cause(self) -> str | None:
        """What the arm met and how hard, while the stop it raised is under way; None
        when it does not know."""


@runtime_checkable
class FeedsParts(Protocol):
    """A backend that drives its own infeed (the twin's ``sim: feed``)."""

    def feed_parts(self) -> list[str]:
        """Put parts that were taken away back at their spawn pose; their names."""


@runtime_checkable
class MeasuresConveyors(Protocol):
    """A backend that reads the cell's conveyor encoders (the twin's belts; SPEC 13)."""

    def conveyor_travel_m(self, name: str) -> float | None:
        """How far conveyor ``name`` has travelled, m, as its encoder reads it now; None
        when this backend cannot measure it."""


@runtime_checkable
class CameraImages(Protocol):
    """A backend that renders the cell cameras itself (the in-process twin)."""

    def camera_image(self, name: str) -> np.ndarray:
        """What cell camera ``name`` sees now (RGB, height x width x 3, uint8); raises
        BackendError for a camera it does not have."""


class DepthRenderer(Protocol):
    """One depth camera's renderer, made by :meth:`RendersDepth.depth_renderer`. It may
    hold a GL context: make, use and close it on one thread (never the control thread)."""

    def frame(self, scene: object, time_s: float) -> Any:
        """The depth image of ``scene`` (a :meth:`RendersDepth.depth_scene`) taken at
        ``time_s`` (s): a :class:`cellrunner.perception.frames.DepthFrame`."""

    def close(self) -> None:
        """Release the renderer; idempotent."""


@runtime_checkable
class RendersDepth(Protocol):
    """A backend that renders the depth cameras of the watched zone itself (the in-process
    twin): the engine copies the scene on the control thread and has it rendered on a
    worker thread."""

    def depth_rates_hz(self) -> dict[str, float]:
        """Each depth camera's name and its frame rate (Hz)."""

    def depth_time_s(self) -> float | None:
        """The backend's clock now (s); None while it is not connected (no images)."""

    def depth_scene(self) -> object:
        """A copy of the scene now (the arm's joints, the moving bodies), to render later
        on another thread; only when connected."""

    def depth_renderer(self, camera: str, range_m: tuple[float, float], seed: int) -> DepthRenderer:
        """A renderer of depth camera ``camera`` that keeps distances within ``range_m``
        (near, far, in m) and draws its noise from ``seed``."""
