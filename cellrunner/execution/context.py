"""What a running job needs, handed to every step: no globals, no singletons."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from cellrunner.backends.base import RobotBackend, RobotState
from cellrunner.model.expand import Step
from cellrunner.model.trajectory import ApprovedTrajectory


class Motions(Protocol):
    """Approved trajectories for a job's motion steps (implemented by the task plan)."""

    def nominal(self, step: Step) -> ApprovedTrajectory | None:
        """The trajectory ``check`` approved for ``step`` (from its planned start); None
        for motions only planned where the arm stands (a retry's in-between steps)."""

    def continues(self, step: Step) -> bool:
        """Whether ``step``'s nominal trajectory continues the motion before it without
        stopping (it was verified starting at that motion's speed, not from rest)."""

    def replan(self, step: Step, q_now_rad: np.ndarray, carrying: bool) -> ApprovedTrajectory:
        """A verified trajectory from ``q_now_rad`` to ``step``'s goal (after a stop, a
        retry); raises InfeasibleError when none passes the checks."""

    def tcp_position_m(self, q_rad: np.ndarray) -> np.ndarray:
        """World position of the TCP at ``q_rad`` (for tracking error)."""


@dataclass
class Carry:
    """The part the gripper holds: the load measured once lifted, for slip detection."""

    baseline_N: np.ndarray
    load_N: float | None = None
    min_N: float = 0.0
    confirm: str | None = None  # input channel that must stay true


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
    step_timeout_s: float = 60.0
    on_step_start: Callable[[Step, int], None] | None = None
    state: RobotState | None = None
    carry: Carry | None = None
    tracking_error_m: float = 0.0
    commanded_q: np.ndarray | None = None
    log: object = None
    notes: dict = field(default_factory=dict)

    @property
    def now_s(self) -> float:
        return self.state.time_s if self.state is not None else 0.0

    def read(self) -> RobotState:
        self.state = self.backend.read_state()
        return self.state
