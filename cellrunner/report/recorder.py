"""What a report needs from a run: samples at a fixed rate and the moments steps start."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cellrunner.model.robot_state import RobotState
    from cellrunner.model.step import Step
    from cellrunner.sim.world import SimWorld

#: samples per simulated second kept for plots (the controller runs at 125-500 Hz)
SAMPLE_HZ = 50.0

#: a step start: (time s, step index, kind, name)
Mark = tuple[float, int, str, str]


@dataclass
class RunRecorder:
    """Samples of one run in the world frame: time (s, from the first sample), joints
    (rad, rad/s, and what the engine commanded), TCP position (m), wrist force magnitude
    (N), IO values by name; ``marks`` are (time s, step index, kind, name) at step starts
    (a retried step appears again)."""

    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    qd: list[np.ndarray] = field(default_factory=list)
    q_cmd: list[np.ndarray] = field(default_factory=list)
    tcp: list[np.ndarray] = field(default_factory=list)
    force_N: list[float] = field(default_factory=list)
    io: dict[str, list[float]] = field(default_factory=dict)  # name -> values, aligned with t
    marks: list[Mark] = field(default_factory=list)
    # (name, MuJoCo qpos) to picture afterwards
    moments: list[tuple[str, np.ndarray]] = field(default_factory=list)
    _next_s: float = -1.0

    def moment(self, name: str, sim_world: SimWorld | None) -> None:
        """Remember the scene's pose now (a grip, a release) to render it after the run;
        the first time only (a grip's weighing after the lift is the grip step again)."""
        if sim_world is not None and all(name != seen for seen, _ in self.moments):
            self.moments.append((name, sim_world.data.qpos.copy()))

    def mark(self, time_s: float, step: Step) -> None:
        self.marks.append((time_s, step.index, step.kind, step.name))

    @property
    def next_due_s(self) -> float:
        """The time (s) from which :meth:`due` is true."""
        return self._next_s

    def due(self, time_s: float) -> bool:
        """Is a sample due at ``time_s`` (s)? (``SAMPLE_HZ`` samples per simulated second)"""
        return time_s >= self._next_s

    def sample(
        self,
        state: RobotState,
        q_cmd_rad: np.ndarray | None,
        p_world_tcp_m: np.ndarray,
        io_names: dict[str, str],
    ) -> None:
        """Keep ``state`` (a RobotState); ``io_names``: IO name -> channel."""
        self._next_s = state.time_s + 1.0 / SAMPLE_HZ
        self.t.append(state.time_s)
        self.q.append(state.q_rad.copy())
        self.qd.append(state.qd_rad_s.copy())
        self.q_cmd.append(
            state.q_rad.copy() if q_cmd_rad is None else np.asarray(q_cmd_rad, float).copy()
        )
        self.tcp.append(np.asarray(p_world_tcp_m, float).copy())
        self.force_N.append(float(np.linalg.norm(state.wrench_N[:3])))
        values = {**state.outputs, **state.inputs}
        for name, channel in io_names.items():
            self.io.setdefault(f"{name} ({channel})", []).append(
                float(values.get(channel, values.get(name, 0.0)) or 0.0)
            )

    @property
    def t0(self) -> float:
        return self.t[0] if self.t else 0.0

    def arrays(self) -> dict[str, np.ndarray]:
        """The samples as arrays, time from the first sample."""
        return {
            "t": np.array(self.t) - self.t0,
            "q": np.array(self.q),
            "qd": np.array(self.qd),
            "q_cmd": np.array(self.q_cmd),
            "tcp": np.array(self.tcp),
            "force": np.array(self.force_N),
        }

    def step_marks(self) -> list[tuple[float, int, str, str]]:
        """Marks with time from the first sample."""
        return [(t - self.t0, i, kind, name) for t, i, kind, name in self.marks]
