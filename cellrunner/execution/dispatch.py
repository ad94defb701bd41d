"""Which behaviour runs an item of a job's agenda: a step as itself (its kind's
:meth:`~cellrunner.model.step_kinds.StepKindDef.run`: a motion, a guarded force line, an
IO or tool step), a grip's weighing, or standing still before on_error."""

from __future__ import annotations

import numpy as np

from cellrunner.execution.belt_tracking import DONE_KEY
from cellrunner.execution.context import JobContext
from cellrunner.execution.job_records import AgendaItem
from cellrunner.execution.outcome import OK, StepGen
from cellrunner.execution.steps import run_weigh
from cellrunner.model.step_kinds import kind_of


def behaviour_of(ctx: JobContext, item: AgendaItem) -> StepGen:
    """The generator that runs ``item``, one tick per ``next``."""
    step = item.step
    if step.index in ctx.notes.get(DONE_KEY, ()):  # run by its tracked stretch
        return _done()
    if item.behaviour == "weigh":
        return run_weigh(ctx, step)
    if item.behaviour == "still":
        return stand_still(ctx)
    behaviour: StepGen = kind_of(step.kind).run(ctx, step, item.resume)
    return behaviour


def _done() -> StepGen:
    return OK
    yield  # a generator


def stand_still(ctx: JobContext) -> StepGen:
    """Wait (at most 2 s) until the arm stands still: after a failure's stop ramp, before
    the first on_error motion."""
    t0 = ctx.now_s
    while np.max(np.abs(ctx.last_state.qd_rad_s)) > 1e-3 and ctx.now_s - t0 < 2.0:
        yield
    yield
    return OK
