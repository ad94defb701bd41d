"""Faults at per-job rates while ``serve`` runs jobs on the twin (``serve --backend sim
--faults FILE``): what a soak needs besides kills, the physical faults of a line (a grip
missed, a part slipping, a protective stop, an e-stop) happening in the twin while the
PLC runs its jobs and clears what stops the cell, as on the line.

Each job draws its faults once, as a shift does (:func:`~cellrunner.execution.shift.draw_faults`:
each fault with its probability, at a step where it can happen; a seeded generator), when
its first step starts. A fault strikes when its step starts (a grip miss, a slip) or a
moment into its motion (a stop), as ``dry-run --inject`` makes it. An e-stop is released
:data:`ESTOP_RELEASE_S` later (the operator); the PLC's Reset recovers the cell. A job a
fault made fail is a result (the PLC reads its code), not a lost job.

``robot_disconnect`` and ``plc_disconnect`` are not among them: the twin's link does not
come back by itself (a soak's kill -9 rehearses a lost link), and a PLC that stops its
heartbeat is the PLC's to rehearse (the watchdog then holds the cell for real).
"""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from cellrunner.execution.shift import draw_faults

if TYPE_CHECKING:
    from cellrunner.execution.cell import CellController
    from cellrunner.model.step import Step

#: the faults ``serve --faults`` makes happen in the twin
SERVE_FAULTS = ("grip_miss", "part_slip", "protective_stop", "estop")
#: a stop strikes this long into its step (s of the twin's time), as ``--inject`` does
STOP_DELAY_S = 0.3
#: the operator releases an e-stop this long after it was pressed (s of the twin's time)
ESTOP_RELEASE_S = 2.0


@dataclass
class ServeFaults:
    """Draws each job's faults and makes them happen: ``on_step_start`` is the
    controller's step hook, the instance itself a control-loop observer."""

    rates: Mapping[str, float]
    seed: int = 0
    log: Any = None
    cell: CellController | None = None
    backend: Any = None
    rng: random.Random = field(init=False)
    #: the running job's drawn faults not struck yet: (fault, expanded step index)
    drawn: list[tuple[str, int]] = field(default_factory=list)
    #: faults due at a time of the twin (s)
    scheduled: list[tuple[str, float]] = field(default_factory=list)
    estop_release_at: float | None = None
    job_id: str | None = None
    #: faults drawn and faults that struck, by name
    drawn_count: Counter[str] = field(default_factory=Counter)
    struck: Counter[str] = field(default_factory=Counter)

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)

    def attach(self, cell: CellController) -> None:
        """Watch ``cell`` (its backend: the twin) once it is assembled."""
        self.cell, self.backend = cell, cell.backend

    def on_step_start(self, step: Step, attempt: int) -> None:
        """A step starts (control thread): a new job draws its faults; this step's are due
        now or a moment into its motion."""
        cell = self.cell
        if cell is None:
            return
        view = cell.job_view(records=False)
        now = self.backend.read_state().time_s
        if view is not None and view.job_id != self.job_id:
            self.job_id = view.job_id
            planned = cell.planned_job()
            steps = planned.run_steps if planned is not None else [step]
            self.drawn = list(draw_faults(self.rng, self.rates, steps))
            self.drawn_count.update(f for f, _ in self.drawn)
        if attempt != 1:
            return
        for item in [d for d in self.drawn if d[1] == step.index]:
            self.drawn.remove(item)
            fault = item[0]
            delay = 0.0
            if fault in ("protective_stop", "estop"):
                moves_s = cell.planned_motion_s(step)
                delay = STOP_DELAY_S if not moves_s else min(STOP_DELAY_S, 0.5 * moves_s)
            self.scheduled.append((fault, now + delay))

    def quiet_until_s(self, cell: CellController) -> float:
        """Until when (s of the twin's time) there is nothing to do (a look-ahead's bound)."""
        times = [at for _, at in self.scheduled]
        if self.estop_release_at is not None:
            times.append(self.estop_release_at)
        return min(times, default=float("inf"))

    def __call__(self, cell: CellController) -> None:
        if not self.scheduled and self.estop_release_at is None:
            return
        now = self.backend.read_state().time_s
        for item in list(self.scheduled):
            fault, at = item
            if now < at:
                continue
            self.scheduled.remove(item)
            self.backend.inject_fault(fault)
            self.struck[fault] += 1
            if self.log is not None:
                self.log.info("fault_injected", fault=fault, job_id=self.job_id)
            if fault == "estop":
                self.estop_release_at = now + ESTOP_RELEASE_S
        if self.estop_release_at is not None and now >= self.estop_release_at:
            self.estop_release_at = None
            self.backend.release_estop()
            if self.log is not None:
                self.log.info("estop_released", by="operator")
