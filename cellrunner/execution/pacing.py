"""Commissioning pace for ``run``: a gate that starts each step only when the operator
says so (``--step``). The approved motions at a fraction of their speed (``--speed``) are
:meth:`JobPlan.paced <cellrunner.planning.job_plan.JobPlan.paced>`. ``serve`` uses
neither: production runs at the approved pace."""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import IO

from cellrunner.model.expand import Step
from cellrunner.model.step import StepKind


class EnterGate:
    """``run --step``: each step waits for a line (Enter) on ``source``; before waiting it
    shows what comes next. Call :meth:`start` once; :meth:`__call__` is the job runner's
    gate and never blocks (it runs on the control thread)."""

    def __init__(
        self,
        describe: Callable[[Step], str],
        source: IO[str] | None = None,
        out: IO[str] | None = None,
        on_end: Callable[[], object] | None = None,
    ) -> None:
        self.describe = describe
        self.on_end = on_end  # called (once) when a step waits and the input has ended
        self.source = source if source is not None else sys.stdin
        self.out = out if out is not None else sys.stderr
        self._lines = threading.Semaphore(0)
        self._asked: int | None = None
        self.closed = False

    def start(self) -> None:
        threading.Thread(target=self._read, name="step-gate", daemon=True).start()

    def _read(self) -> None:
        for _ in self.source:
            self._lines.release()
        self.closed = True  # end of input: nobody can press Enter any more

    def __call__(self, step: Step) -> bool:
        if self._asked != step.index:
            self._asked = step.index
            while self._lines.acquire(blocking=False):
                pass  # Enters typed ahead of the question do not count
            self.out.write(
                f"next: {self.describe(step)}\n  press Enter to run it (Ctrl-C aborts)\n"
            )
            self.out.flush()
        if self._lines.acquire(blocking=False):
            return True
        if self.closed and self.on_end is not None:
            self.out.write("end of input: no one can confirm the next step; aborting\n")
            self.on_end()
            self.on_end = None
        return False


def describe_step(step: Step) -> str:
    """One line on what a step will do: its label and target (world frame, m and deg)."""
    from cellrunner.model.geometry import rpy_deg_of

    text = step.label
    if step.T_world_tcp is not None:
        xyz, rpy = step.T_world_tcp[:3, 3], rpy_deg_of(step.T_world_tcp[:3, :3])
        text += (
            f": TCP to xyz [{', '.join(f'{v:.4f}' for v in xyz)}] m, "
            f"rpy [{', '.join(f'{v:.2f}' for v in rpy)}] deg in world"
        )
    elif step.q_goal_deg is not None:
        text += f": joints to [{', '.join(f'{v:.2f}' for v in step.q_goal_deg)}] deg"
    elif step.is_motion:
        distance = getattr(step.args, "distance", None)
        text += f": {distance:g} m straight" if distance is not None else ""
    elif step.kind not in (StepKind.GRIP, StepKind.RELEASE):
        text += f": {step.args}"
    return text
