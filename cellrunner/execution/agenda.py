"""What a job runs now: the items still to come (:class:`AgendaItem`), the one under way
with its generator, when it started and how long it may take. With a gate (``run
--step``) a step stands still until the gate lets it start."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from cellrunner.execution.context import JobContext
from cellrunner.execution.dispatch import behaviour_of
from cellrunner.execution.job_records import AgendaItem, StepRows
from cellrunner.execution.outcome import OK, StepGen
from cellrunner.model.expand import Step


class Agenda:
    """``items`` to run in order; ``current`` the one under way (None: none is left),
    ``gen`` its generator (None after a hold or a reconnect dropped it), ``started_s`` and
    ``timeout_s`` its start (robot time, s) and how long it may take (s)."""

    def __init__(
        self,
        ctx: JobContext,
        rows: StepRows,
        steps: list[Step],
        gate: Callable[[Step], bool] | None,
        log: Callable[..., None],
    ) -> None:
        self.ctx, self._rows, self._gate, self._log = ctx, rows, gate, log
        self.items = [AgendaItem(s) for s in steps]
        self.current: AgendaItem | None = None
        self.gen: StepGen | None = None
        self.started_s = 0.0
        self.timeout_s = 0.0

    @property
    def step_index(self) -> int | None:
        return self.current.step.index if self.current is not None else None

    @property
    def label(self) -> str:
        return self.current.step.label if self.current else "the job"

    def timed_out(self) -> bool:
        return self.ctx.last_state.time_s - self.started_s > self.timeout_s

    def next(self, items: list[AgendaItem] | None = None) -> None:
        """Start the next item (of ``items``, when given, instead of those left)."""
        if items is not None:
            self.items = items
        self.current = self.items.pop(0) if self.items else None
        if self.current is not None:
            self.start(self.current)

    def restart(self) -> None:
        """Start the item under way again, resuming from where the arm stands."""
        if self.current is not None:
            self.current.resume = True
            self.start(self.current)

    def drop_motion(self) -> None:
        """Forget the item's generator and the motion it streamed (a hold, a reconnect): no
        tracking error until the next set-point."""
        self.gen = None
        self.ctx.stream = self.ctx.hold = None
        self.ctx.commanded_q = None

    def start(self, item: AgendaItem) -> None:
        step, ctx = item.step, self.ctx
        ctx.hold = None
        ctx.stream = None  # a motion's generator sets it once it streams
        if (
            self._gate is not None
            and not (item.gated or item.between or item.resume)
            and item.behaviour == "step"
        ):
            self.timeout_s = math.inf
            self.gen = self._await_gate(self._gate, item)
            return
        self.started_s = ctx.now_s
        self.timeout_s = item.timeout_s(ctx.step_timeout_s)
        if not item.between and item.behaviour == "step" and not item.resume:
            if ctx.on_step_start is not None:
                ctx.on_step_start(step, item.attempt)
            self._rows.started(step.index, item.attempt, ctx.now_s)
        fields: dict[str, Any] = {"between": item.between or None, "resume": item.resume or None}
        self._log("step", kind=step.kind, name=step.name, attempt=item.attempt, **fields)
        self.gen = behaviour_of(ctx, item)

    def _await_gate(self, gate: Callable[[Step], bool], item: AgendaItem) -> StepGen:
        """Stand still until the gate opens, then start the item (its own behaviour runs
        from the next tick on)."""
        while not gate(item.step):
            yield
        item.gated = True
        self.start(item)
        yield
        return OK  # not reached: start replaced this generator
