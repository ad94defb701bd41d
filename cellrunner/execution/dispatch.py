"""Which behaviour runs an item of a job's agenda: a step as itself (a motion, a guarded
force line, an IO or tool step), a grip's weighing, or standing still before on_error."""

from __future__ import annotations

import numpy as np

from cellrunner.execution import steps as behaviours
from cellrunner.execution.align import run_align
from cellrunner.execution.context import JobContext
from cellrunner.execution.force import run_force
from cellrunner.execution.job_records import AgendaItem
from cellrunner.execution.outcome import OK, StepGen
from cellrunner.execution.steps import run_motion, run_weigh
from cellrunner.execution.tool_change import run_tool_lock, run_tool_unlock
from cellrunner.model.force_steps import FORCE_KINDS
from cellrunner.model.step import StepKind

#: the behaviour of each step kind that is not a motion
_BEHAVIOURS = {
    **behaviours.BEHAVIOURS,
    StepKind.TOOL_LOCK: run_tool_lock,
    StepKind.ALIGN: run_align,
    StepKind.TOOL_UNLOCK: run_tool_unlock,
}


def behaviour_of(ctx: JobContext, item: AgendaItem) -> StepGen:
    """The generator that runs ``item``, one tick per ``next``."""
    step = item.step
    if item.behaviour == "weigh":
        return run_weigh(ctx, step)
    if item.behaviour == "still":
        return stand_still(ctx)
    if step.kind in FORCE_KINDS:  # a guarded line
        return run_force(ctx, step, resume=item.resume)
    if step.is_motion:
        return run_motion(ctx, step, resume=item.resume)
    return _BEHAVIOURS[step.kind](ctx, step)


def stand_still(ctx: JobContext) -> StepGen:
    """Wait (at most 2 s) until the arm stands still: after a failure's stop ramp, before
    the first on_error motion."""
    t0 = ctx.now_s
    while np.max(np.abs(ctx.last_state.qd_rad_s)) > 1e-3 and ctx.now_s - t0 < 2.0:
        yield
    yield
    return OK
