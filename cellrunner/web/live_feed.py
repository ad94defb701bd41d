"""The measured arm for the live 3D view, sampled on the control thread.

:class:`LiveFeed` is one of the control loop's observers
(:class:`~cellrunner.execution.loop.ControlLoop`): once every ``1 / rate_hz`` seconds of
wall clock it copies what the backend measured this period (its clock, the joints), the
cell's status and the running job's plan into a frozen :class:`LiveSample`, and publishes
it by replacing one reference. Nothing on the control thread waits: no lock, no I/O, no
kinematics (the readers on the web threads compute link poses from the sample). Between
samples the observer costs one clock read.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from cellrunner.errors import InternalError
from cellrunner.execution.cell import CellController
from cellrunner.execution.planner import PlannedJob

#: samples per second of wall clock (the page redraws the arm at this rate)
DEFAULT_RATE_HZ = 20.0


@dataclass(frozen=True)
class LiveSample:
    """The arm as measured at backend time ``time_s`` (s): joints ``q_rad`` (controller
    convention), the job under way (``job_id`` "" when none, ``step_index`` 1-based, 0 =
    none) and its plan once ready; ``seq`` counts samples from 1."""

    seq: int
    time_s: float
    q_rad: tuple[float, ...]
    job_id: str
    step_index: int
    plan: PlannedJob | None
    obstructed: bool
    obstruction: str
    sampled_at_s: float  # time.monotonic() when taken


class LiveFeed:
    """The control loop's observer that samples the arm (module docstring)."""

    def __init__(self, rate_hz: float = DEFAULT_RATE_HZ) -> None:
        if not rate_hz > 0:
            raise InternalError(f"rate_hz must be > 0, got {rate_hz!r}")
        self.period_s = 1.0 / rate_hz
        self._next_s = 0.0
        self._seq = 0
        #: the last sample (None before the first period); replaced, never changed
        self.latest: LiveSample | None = None

    def __call__(self, cell: CellController) -> None:
        now = time.monotonic()
        if now < self._next_s:
            return
        # on schedule, without drifting when a period ran late
        self._next_s = max(self._next_s + self.period_s, now)
        state = cell.backend.read_state()  # this period's (the backends cache it)
        status = cell.status()
        self._seq += 1
        self.latest = LiveSample(
            seq=self._seq,
            time_s=float(state.time_s),
            q_rad=tuple(float(v) for v in state.q_rad),
            job_id=status.job_id,
            step_index=status.step_index,
            plan=cell.planned_job() if status.job_id else None,
            obstructed=status.obstructed,
            obstruction=status.obstruction,
            sampled_at_s=now,
        )
