"""The real cell for the PLC soak: the cell controller and job runner driving the MuJoCo
twin (unpaced, as fast as it steps), with random faults injected into the twin.

    PYTHONPATH=. python bench/bench_plc.py --cell bench.soak_engine:make --jobs 200

Faults (per job, seeded): grip_miss, part_slip, protective_stop, estop (released after
0.5 s, so that the PLC's RESET clears it), robot_disconnect (reconnects on Clear).
The twin's infeed puts a new part at the pick frame before every job.
"""

from __future__ import annotations

import random
import shutil
import tempfile
import threading
import time
from pathlib import Path

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner, warm_up
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.world import CellWorld
from cellrunner.sim.from_cell import description_of

ROOT = Path(__file__).resolve().parent.parent
FAULTS = ("grip_miss", "part_slip", "protective_stop", "estop", "robot_disconnect")


class SoakCell(CellController):
    """A CellController with its own control thread and a seeded fault injector."""

    def __init__(self, fault_rate: float = 0.25, seed: int = 7):
        cell = load_cell(ROOT / "cells" / "demo_ur5e.yaml")
        tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
        world = CellWorld(cell)
        warm_up(world)  # as serve does before READY
        self.sim = SimBackend(description_of(cell))
        # a journal file, as serve's (an in-memory one would grow the process with every job)
        self._journal_dir = Path(tempfile.mkdtemp(prefix="cellrunner-soak-"))
        super().__init__(
            cell,
            tasks,
            self.sim,
            Journal(self._journal_dir / "jobs.sqlite"),
            job_planner(world),
            wait_for_unhold=False,
            on_step_start=self._maybe_inject,
            on_job_start=self.sim.feed_parts,
        )
        self.rng = random.Random(seed)
        self.fault_rate = fault_rate
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._armed: tuple[str, int] | None = None
        self._release_at: float | None = None
        self.injected: dict[str, int] = {}

    def start(self) -> SoakCell:
        self.setup()
        self._thread = threading.Thread(target=self._loop, name="soak-control", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
        super().close()
        shutil.rmtree(self._journal_dir, ignore_errors=True)

    def start_job(self, task, params, client_job_id, source):
        ticket = super().start_job(task, params, client_job_id, source)
        if ticket.accepted and self.rng.random() < self.fault_rate:
            self._armed = (self.rng.choice(FAULTS), self.rng.randint(2, 9))
        return ticket

    def _maybe_inject(self, step, attempt) -> None:
        if self._armed and step.index == self._armed[1] and attempt == 1:
            fault = self._armed[0]
            self._armed = None
            self.sim.inject_fault(fault)
            self.injected[fault] = self.injected.get(fault, 0) + 1
            if fault == "estop":
                self._release_at = self.sim.read_state().time_s + 0.5

    def _loop(self) -> None:
        ControlLoop(self, observers=(self._observe,)).run(self._stop)

    def _observe(self, cell: CellController) -> None:
        if self._release_at is not None and self.sim.read_state().time_s >= self._release_at:
            self.sim.release_estop()  # the operator releases it; the PLC's RESET clears
            self._release_at = None
        if not cell.busy:
            time.sleep(0.002)  # idle: don't spin the physics faster than the PLC can talk


def make() -> SoakCell:
    return SoakCell()
