"""The correction an ``align`` step measured (see :mod:`cellrunner.execution.align`),
carried to the later steps aimed at the same frame."""

from __future__ import annotations

import dataclasses

import numpy as np

from cellrunner.execution.context import JobContext
from cellrunner.model.step import Step


def corrected(ctx: JobContext, step: Step) -> Step | None:
    """``step`` moved by the correction an align measured for the frame it aims at (None
    when no align corrects it)."""
    frame = step.extra.get("aligned_frame")
    C = ctx.notes.get("align", {}).get(frame) if frame is not None else None
    if C is None or step.T_world_tcp is None:
        return None
    F = step.extra["T_world_frame"]
    T = F @ C @ np.linalg.inv(F) @ step.T_world_tcp
    return dataclasses.replace(step, T_world_tcp=T, extra={**step.extra, "corrects": step})
