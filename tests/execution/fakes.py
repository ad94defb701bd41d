"""A scripted kinematic arm and straight-line motions for tick-by-tick engine tests.

Not a protocol mock: the engine's Protocol boundary is Python here; the real backends
are tested against the MuJoCo twin and the virtual UR controller over real sockets.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cellrunner.errors import BackendError
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.model.expand import Step, expand
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.model.trajectory import Trajectory, approve
from tests.conftest import DEMO_CELL

RATE = 500.0


@dataclass
class ScriptedArm:
    """q follows servo set-points exactly; the gripper closes on a part when one is there."""

    part_present: bool = True
    part_mass_kg: float = 0.3
    close_channel: str = "DO0"
    sensor_channel: str = "DI0"
    close_ticks: int = 40
    drop_part_at_s: float | None = None
    protective_stop_at_s: float | None = None
    estop_at_s: float | None = None
    disconnect_at_s: float | None = None
    rate_hz: float = RATE
    reconnect_timeout_s: float = 0.0
    t: float = 0.0
    q: np.ndarray = field(default_factory=lambda: np.zeros(6))
    qd: np.ndarray = field(default_factory=lambda: np.zeros(6))
    outputs: dict = field(default_factory=dict)
    safety: Safety = Safety.NORMAL
    stopped_at_s: float | None = None
    unlock_refusals: int = 0
    estop_released: bool = False
    powered: bool = True
    power_up_ticks: int = 1  # recover_from_estop_steps: steps until powered (a real arm: seconds)
    servo_count: int = 0
    _closing_ticks: int = 0
    _holding_part: bool = False
    _lifted: bool = False  # the fake's lift raises joint 3 above 0
    _target: np.ndarray | None = None

    def connect(self):
        pass

    def reconnect(self, timeout_s=None):
        pass

    def job_started(self):
        pass

    def close(self):
        pass

    def zero_ft_sensor(self):
        pass

    def set_tool(self, T_flange_tcp, payload_kg, payload_cog_m):
        pass

    def recover_from_estop(self):
        for _ in self.recover_from_estop_steps():
            pass

    def recover_from_estop_steps(self):
        if self.safety is Safety.EMERGENCY_STOP:
            raise BackendError("emergency stop is still pressed; a person must release it first")
        for _ in range(self.power_up_ticks):
            yield
        self.powered = True

    def read_state(self) -> RobotState:
        closed_on_part = self._holding_part
        wrench = np.zeros(6)
        wrench[2] = -20.0  # the tool's own weight
        if closed_on_part and self._lifted:  # off the table: the wrist carries the part
            wrench[2] -= self.part_mass_kg * 9.81
        return RobotState(
            self.t,
            self.q.copy(),
            self.qd.copy(),
            wrench,
            self.safety,
            inputs={self.sensor_channel: closed_on_part},
            outputs=dict(self.outputs),
            powered=self.powered,
        )

    def servo(self, approved, index):
        if not approved.is_sealed:
            raise BackendError("unsealed trajectory")
        if self.safety is Safety.NORMAL:
            self._target = approved.trajectory.q_rad[index]
            self.servo_count += 1

    def stop_motion(self):
        self._target = None

    def set_output(self, channel, value):
        self.outputs[channel] = value
        if channel == self.close_channel:
            self._closing_ticks = 0 if value else -1
            if not value:
                self._holding_part = False

    def unlock_protective_stop(self):
        if self.safety is not Safety.PROTECTIVE_STOP:
            return
        if self.t - self.stopped_at_s < 5.0:
            self.unlock_refusals += 1
            raise BackendError("Cannot unlock protective stop until 5s after occurrence.")
        self.safety = Safety.NORMAL

    def wait_period(self):
        self.t += 1.0 / self.rate_hz
        q0 = self.q.copy()
        if self._target is not None and self.safety is Safety.NORMAL:
            self.q = self._target.copy()
        self.qd = (self.q - q0) * self.rate_hz
        self._lifted = self._holding_part and (self._lifted or self.q[2] > 0.0)
        if self.outputs.get(self.close_channel) and self._closing_ticks >= 0:
            self._closing_ticks += 1
            if self._closing_ticks >= self.close_ticks and self.part_present:
                self._holding_part = True
        for attr, effect in (
            ("protective_stop_at_s", Safety.PROTECTIVE_STOP),
            ("estop_at_s", Safety.EMERGENCY_STOP),
            ("disconnect_at_s", Safety.DISCONNECTED),
        ):
            at = getattr(self, attr)
            if at is not None and self.t >= at:
                setattr(self, attr, None)
                self.safety = effect
                self.stopped_at_s = self.t
                self._target = None
                self.qd = np.zeros(6)
        if self.safety is Safety.EMERGENCY_STOP and self.estop_released:
            self.safety, self.powered = Safety.NORMAL, False  # released: arm powered off
        if self.drop_part_at_s is not None and self.t >= self.drop_part_at_s and self._holding_part:
            self._holding_part = False
            self.part_present = False
            self.drop_part_at_s = None


class LineMotions:
    """Straight joint lines to a per-step goal: lifts raise joint 3 to +0.2 rad, the rest
    move around below 0 (so the fake arm's 'lifted' test reads the load)."""

    def __init__(self, steps: list[Step], duration_s: float = 0.2):
        self.duration_s = duration_s
        self.goal: dict[int, np.ndarray] = {}
        self.kinds = {step.index: step.kind for step in steps}
        self.start: dict[int, np.ndarray] = {}
        q = np.zeros(6)
        for step in steps:
            if step.is_motion:
                self.start[step.index] = q
                q = np.full(6, -0.01 * step.index)
                if step.kind == "lift":
                    q = q.copy()
                    q[2] = 0.2
                self.goal[step.index] = q
        self.replans = 0

    def _line(self, step, q0, q1):
        n = max(2, int(self.duration_s * RATE))
        s = np.linspace(0, 1, n)[:, None]
        return approve(
            Trajectory(RATE, np.arange(n) / RATE, q0 + s * (q1 - q0)), step.index, step.name
        )

    def continues(self, step):
        return False  # every line starts and ends at rest

    def nominal(self, step):
        if step.index not in self.start or step.kind != self.kinds.get(step.index):
            return None  # a retry's in-between motion: planned where the arm stands
        return self._line(step, self.start[step.index], self.goal[step.index])

    def replan(self, step, q_now_rad, carrying):
        self.replans += 1
        if step.kind != self.kinds.get(step.index):
            return self._line(step, q_now_rad, q_now_rad + 0.05)
        return self._line(step, q_now_rad, self.goal[step.index])

    def tcp_position_m(self, q_rad):
        return np.asarray(q_rad[:3])


@dataclass(frozen=True)
class FakePlan:
    """A job's plan as the cell runs it (:class:`~cellrunner.execution.planner.PlannedJob`)."""

    run_steps: list[Step]
    motions: LineMotions
    planned_cycle_time_s: float


#: a job the fakes run ends within this many ticks
MAX_TICKS = 200_000


def planner(loaded, params, q_now):
    cell = load_cell(DEMO_CELL)
    steps = expand(loaded, cell.cell, params)
    return FakePlan(steps, LineMotions(steps), 1.0)


def make_cell(tmp_path, arm=None):
    """The demo cell's controller on a :class:`ScriptedArm` (journal in ``tmp_path``),
    set up and in Idle: (controller, arm)."""
    cell = load_cell(DEMO_CELL)
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    arm = arm or ScriptedArm()
    controller = CellController(cell, tasks, arm, Journal(tmp_path / "jobs.sqlite"), planner)
    controller.setup()
    tick(controller, 2)  # Resetting -> Idle
    return controller, arm


def tick(cell, n=1):
    """``n`` controller periods of ``cell``."""
    for _ in range(n):
        cell.backend.wait_period()
        cell.tick()


def run(runner, arm, until=None):
    """Start ``runner`` and tick it on ``arm`` until it is done (or ``until(runner)``)."""
    runner.start()
    for _ in range(MAX_TICKS):
        if runner.done or (until and until(runner)):
            return runner
        arm.wait_period()
        runner.tick()
    raise AssertionError("job did not end within the tick budget")
