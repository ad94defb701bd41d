"""What a running job needs, handed to every step: no globals, no singletons."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cellrunner.backends.base import RobotBackend
from cellrunner.model.expand import Step
from cellrunner.model.robot_state import RobotState
from cellrunner.model.trajectory import ApprovedTrajectory

if TYPE_CHECKING:
    from cellrunner.execution.belt_watch import BeltWatch
    from cellrunner.execution.obstacle_guard import ObstacleGuard
    from cellrunner.model.align import Marker, Sighting
    from cellrunner.model.cell import Gripper, Tool
    from cellrunner.model.geometry import Placed


class Motions(Protocol):
    """Approved trajectories for a job's motion steps (implemented by the task plan)."""

    def nominal(self, step: Step) -> ApprovedTrajectory | None:
        """The trajectory ``check`` approved for ``step`` (from its planned start); None
        for motions only planned where the arm stands (a retry's in-between steps)."""

    def continues(self, step: Step) -> bool:
        """Whether ``step``'s nominal trajectory continues the motion before it without
        stopping (it was verified starting at that motion's speed, not from rest)."""

    def replan(
        self,
        step: Step,
        q_now_rad: np.ndarray,
        carrying: bool,
        obstacles: Placed | None = None,
    ) -> ApprovedTrajectory:
        """A verified trajectory from ``q_now_rad`` to ``step``'s goal (after a stop, a
        retry), around ``obstacles`` too (the watched zone's map) when given; raises
        InfeasibleError when none passes the checks."""

    def tcp_position_m(self, q_rad: np.ndarray, step: Step | None = None) -> np.ndarray:
        """World position of the TCP at ``q_rad`` (for tracking error), with the tool
        mounted at ``step`` (default: the one mounted at the start)."""

    def tcp_positions_m(self, q_rad: np.ndarray) -> np.ndarray:
        """:meth:`tcp_position_m` (default tool) of each row of ``q_rad`` (N x 6) at once,
        N x 3; equal to it within 1e-9 m (not bit for bit)."""

    def tcp_pose(self, q_rad: np.ndarray) -> np.ndarray:
        """T_world_tcp (4x4) at ``q_rad``, with the tool mounted at the start."""


class Eye(Protocol):
    """What an ``align`` step sees through the cell's cameras (the vision package gives
    one: :class:`cellrunner.vision.eye.MarkerEye`)."""

    def sight(self, camera: str, marker: Marker) -> Sighting | None:
        """Look through ``camera`` now: the marker, or None when it is not in the picture."""
        ...


class EventLog(Protocol):
    """Where a job's events go (a structlog logger bound to the cell and job)."""

    def info(self, event: str, **fields: Any) -> Any: ...

    def warning(self, event: str, **fields: Any) -> Any: ...

    def bind(self, **fields: Any) -> EventLog: ...


class _Quiet:
    """An :class:`EventLog` that drops every event (a cell run without logging)."""

    def info(self, event: str, **fields: Any) -> None:
        pass

    def warning(self, event: str, **fields: Any) -> None:
        pass

    def bind(self, **fields: Any) -> EventLog:
        return self


#: where events go when nobody asked for them
QUIET: EventLog = _Quiet()


@dataclass
class Carry:
    """The part the gripper holds: the load measured once lifted, for slip detection."""

    baseline_N: np.ndarray
    load_N: float | None = None
    min_N: float = 0.0
    confirm: str | None = None  # input channel that must stay true
    tool_mass_kg: float = 0.0  # the mounted tool's, whose inertia the wrist reads in motion


@dataclass
class Stream:
    """A motion being streamed: its approved trajectory and the index of the set-point
    it sends next (the one before it is the set-point commanded now)."""

    approved: ApprovedTrajectory
    next_index: int
    #: the TCP's planned acceleration per set-point (N x 3, m/s^2, base axes), while a
    #: part is carried: the load check takes the tool's inertia out of the wrist reading
    tcp_accel_mps2: np.ndarray | None = None
    gravity_mps2: np.ndarray | None = None  # in base axes, with tcp_accel_mps2


@dataclass
class Hold:
    """A step waiting with the arm's set-point unchanged (a grip, a weighing, a release,
    a wait), set just before it yields. From the next period on, while every input reads
    what it reads now, it yields again in each period at time ``t`` (s) unless
    ``t - t0_s >= timeout_s`` or not ``t - t0_s < until_s``; each period it passes with
    ``t - t0_s >= sample_from_s`` appends that period's wrench (first three, N) to
    ``samples``. A look-ahead (:mod:`~cellrunner.execution.lookahead`) uses this to run
    such periods in one call."""

    t0_s: float
    until_s: float = math.inf
    timeout_s: float = math.inf
    sample_from_s: float = math.inf
    samples: list[np.ndarray] | None = None


@dataclass
class JobContext:
    backend: RobotBackend
    motions: Motions
    outputs: dict[str, str]  # IO name -> channel
    inputs: dict[str, str]
    gripper_close: tuple[str, bool | float] | None  # (channel, value) that closes the jaws
    gripper_open: tuple[str, bool | float] | None
    gripper_closed_sensor: str | None  # channel
    gripper_open_s: float = 0.0  # a release waits at least this long: the jaws clear the part
    gripper_blow_off: tuple[str, float] | None = None  # (channel, pulse s) of a vacuum gripper
    gripper_kind: str = "io"
    tools: dict[str, Tool] = field(
        default_factory=dict
    )  # tool name -> its Gripper (change_tool switches)
    tool_mass_kg: float = 0.0  # the mounted tool's payload (change_tool switches)
    step_timeout_s: float = 60.0
    on_step_start: Callable[[Step, int], None] | None = None
    state: RobotState | None = None
    carry: Carry | None = None
    tracking_error_m: float = 0.0
    commanded_q: np.ndarray | None = None
    stream: Stream | None = None  # the motion under way, while its set-points stream
    hold: Hold | None = None  # what the step waits for, set by it in the current tick
    log: EventLog | None = None
    notes: dict[str, Any] = field(default_factory=dict)
    eye: Eye | None = None  # the cameras, for align steps
    obstacles: ObstacleGuard | None = None  # a watched cell's map on the job's path (SPEC 12)
    belts: BeltWatch | None = None  # the conveyors' encoders and eyes (SPEC 13)

    @property
    def now_s(self) -> float:
        return self.state.time_s if self.state is not None else 0.0

    @property
    def last_state(self) -> RobotState:
        """The state read last (steps run only after the runner's first read)."""
        if self.state is None:
            raise RuntimeError("no robot state has been read yet")
        return self.state

    def read(self) -> RobotState:
        self.state = self.backend.read_state()
        if self.belts is not None:
            self.belts.note(self.state)
        return self.state

    def track(self) -> None:
        """Sample the tracking error: the TCP distance (m) between the set-point streamed
        last and where the arm is (read last)."""
        if self.commanded_q is None:
            return
        p_cmd = self.motions.tcp_position_m(self.commanded_q)
        p_meas = self.motions.tcp_position_m(self.last_state.q_rad)
        error = math.dist(p_cmd.tolist(), p_meas.tolist())
        if error > self.tracking_error_m:
            self.tracking_error_m = error


def use_gripper(ctx: JobContext, gripper: Gripper | None) -> None:
    """Point the context's gripper channels at ``gripper`` (None: nothing mounted)."""
    from cellrunner.model.gripper import gripper_channels
    from cellrunner.model.timing import release_time_s

    ctx.gripper_close, ctx.gripper_open, ctx.gripper_closed_sensor = gripper_channels(
        gripper, ctx.outputs, ctx.inputs
    )
    ctx.gripper_open_s = release_time_s(gripper)
    ctx.gripper_kind = getattr(gripper, "kind", "none")
    blow = getattr(gripper, "blow_off", None)
    ctx.gripper_blow_off = (ctx.outputs[blow.output], blow.pulse) if blow is not None else None
