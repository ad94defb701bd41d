"""The control loop: the one place that owns the clock of a cell.

Every period :class:`ControlLoop` calls ``backend.wait_period()`` (the UR backend waits
for the controller's next cycle; the sim backend advances its physics one period), then
``cell.tick()``, then each observer with the cell. With ``realtime=True`` it also paces
the ticks to the wall clock (the in-process twin, which would otherwise run as fast as
the CPU allows); without, it runs as fast as the backend lets it (dry-run, benches,
tests). ``serve``, ``run``, ``dry-run``, the benches and tests all drive a cell through
it; observers are how a caller watches (records, injects faults) without owning the loop.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from cellrunner.execution.cell import CellController

Observer = Callable[[CellController], None]

#: the most periods one look-ahead covers (the backend may cover fewer)
LOOKAHEAD_PERIODS = 1024

#: a real-time loop that fell this far behind the wall clock restarts its schedule (s)
MAX_LAG_S = 0.5

#: the most simulated time one look-ahead of a running job covers in :meth:`ControlLoop.run`
#: (s; serve on a twin at its fastest): a PLC's command (HOLD, STOP) that arrives during
#: one is taken at its end, at most this much of the twin's time later (a look-ahead's
#: cost is fixed plus per period: shorter ones cost more than the periods they save)
RUN_AHEAD_S = 2.0


class ControlLoop:
    """Ticks one :class:`CellController`; see the module docstring."""

    def __init__(
        self,
        cell: CellController,
        *,
        realtime: bool = False,
        observers: tuple[Observer, ...] = (),
        lookahead: bool = True,
    ) -> None:
        self.cell = cell
        self.realtime = realtime
        #: run_job advances streamed motions many periods per call where the backend can
        #: look ahead and every observer says when it next needs a period
        #: (``quiet_until_s(cell)``); False: always one period at a time
        self.lookahead = lookahead and not realtime
        self.period_s = 1.0 / cell.backend.rate_hz
        self.observers: list[Observer] = list(observers)
        self.ticks = 0
        self.ticks_ahead = 0  # of which in look-aheads
        self._next_wall_s: float | None = None
        #: :meth:`run` (serve on a twin at its fastest): the periods of a running job's
        #: motions in look-aheads of at most RUN_AHEAD_S (where ``lookahead`` allows)
        self.run_ahead = False

    def add_observer(self, observer: Observer) -> None:
        self.observers.append(observer)

    def step(self, n: int = 1) -> None:
        """``n`` periods: wait, tick, observers."""
        for _ in range(n):
            self.cell.backend.wait_period()
            self.cell.tick()
            self.ticks += 1
            for observer in self.observers:
                observer(self.cell)
            if self.realtime:
                self._pace()

    def run(self, stop: threading.Event) -> None:
        """Tick until ``stop`` is set (serve)."""
        cell = self.cell
        while not stop.is_set():
            if self.run_ahead and self.lookahead and cell.busy and not cell.planning:
                now_s = cell.backend.read_state().time_s
                periods = min(LOOKAHEAD_PERIODS, max(1, round(RUN_AHEAD_S / self.period_s)))
                if self._fast_forward(now_s + RUN_AHEAD_S, periods):
                    continue
            self.step()

    def run_job(self, *, max_s: float, stop: threading.Event | None = None) -> None:
        """Tick until the cell's job ended and its end was shown (Completing/Aborting
        passed), or abort it once ``max_s`` of backend time (or 4x that, at least 60 s,
        of wall time) passed. While the job plans the loop waits for the planner instead
        of spinning the backend."""
        cell = self.cell
        t0 = cell.backend.read_state().time_s
        deadline_wall = time.monotonic() + max(60.0, max_s * 4)
        while cell.busy:
            if stop is not None and stop.is_set():
                return
            if cell.planning and not cell.wait_for_plan(timeout_s=1.0):
                if time.monotonic() > deadline_wall:
                    cell.command("abort")
                continue  # still planning: don't spin the physics
            if cell.backend.read_state().time_s - t0 > max_s or time.monotonic() > deadline_wall:
                cell.command("abort")
                self.step()
                return
            if self.lookahead and self._fast_forward(t0 + max_s):
                continue
            self.step()

    def _fast_forward(self, limit_s: float, max_periods: int = LOOKAHEAD_PERIODS) -> int:
        """Periods advanced by the cell in one look-ahead (none past ``limit_s`` or the
        moment an observer asks for), 0 when the next period runs as usual."""
        until_s = limit_s
        for observer in self.observers:
            quiet_until = getattr(observer, "quiet_until_s", None)
            if quiet_until is None:
                return 0
            until_s = min(until_s, quiet_until(self.cell))
        n = self.cell.fast_forward(max_periods, until_s)
        self.ticks += n
        self.ticks_ahead += n
        return n

    def _pace(self) -> None:
        now = time.monotonic()
        if self._next_wall_s is None:
            self._next_wall_s = now
        self._next_wall_s += self.period_s
        delay = self._next_wall_s - now
        if delay > 0:
            time.sleep(delay)
        elif delay < -MAX_LAG_S:
            self._next_wall_s = now  # fell behind: don't catch up in a burst
