"""A job's watch on its path (SPEC 12): the zone's map, the task's ``on_obstacle``
policy, and what happened (stops, waits, replans), for the log and the report. The
streaming under it is :mod:`cellrunner.execution.obstacles`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from cellrunner.execution.watch import ZoneWatch
    from cellrunner.model.geometry import Placed
    from cellrunner.model.task import ObstaclePolicy
    from cellrunner.perception.path_check import Blocked


class _Clock(Protocol):
    """What a note reads of the job (its :class:`~cellrunner.execution.context.JobContext`):
    the time (s), the set-point streamed last, the state read last, the motions (for the
    TCP), the log."""

    @property
    def now_s(self) -> float: ...

    @property
    def commanded_q(self) -> np.ndarray | None: ...

    @property
    def last_state(self) -> Any: ...

    @property
    def motions(self) -> Any: ...

    @property
    def log(self) -> Any: ...


@dataclass
class ObstacleGuard:
    """A job's watch on its path: the map, the task's policy, the joints' acceleration
    limits (rad/s^2) for stops on the path; ``obstructed`` says where while the arm waits."""

    zone: ZoneWatch
    policy: ObstaclePolicy
    accel_rad_s2: np.ndarray
    obstructed: str = ""
    held: Placed | None = None  # the part carried in the last watched motion
    why_not: str = ""  # why the last replan found no way
    replans: int = 0
    last_replan_s: float = -math.inf
    events: list[dict[str, Any]] = field(default_factory=list)

    def note(self, ctx: _Clock, what: str, blocked: Blocked | None, **extra: Any) -> None:
        event: dict[str, Any] = {"what": what, "time_s": round(ctx.now_s, 4)}
        q = ctx.commanded_q if ctx.commanded_q is not None else ctx.last_state.q_rad
        event["tcp_m"] = [round(float(v), 4) for v in ctx.motions.tcp_position_m(q)]
        if blocked is not None:
            event["voxel_m"] = [round(v, 3) for v in blocked.voxel_m]
        event.update(extra)
        self.events.append(event)
        if ctx.log is not None:
            ctx.log.info("obstacle", **event)

    def summary(self, step_index: int) -> str:
        """One line of what obstacles did to a step, for its journal row: each stop, wait,
        replan and clear with its time (s) and the voxel's position (m); "" when none."""
        parts = []
        for e in self.events:
            if e.get("step") != step_index:
                continue
            text = f"{e['what']} {e['time_s']:.2f} s"
            if "voxel_m" in e:
                x, y, z = e["voxel_m"]
                text += f" at ({x:.2f}, {y:.2f}, {z:.2f}) m"
            parts.append(text)
        return "obstacle: " + "; ".join(parts) if parts else ""
