"""The real cell controller on a MuJoCo twin backend, in this process, for tests that
drive jobs period by period."""

from __future__ import annotations

from typing import Any

from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.model.load import LoadedCell


def twin_cell(
    cell: LoadedCell, tasks: dict[int, Any], backend: Any, **kw: Any
) -> tuple[CellController, ControlLoop]:
    """The controller of ``cell`` running ``tasks`` on ``backend`` (planned afresh, no plan
    cache; an in-memory journal; ``kw`` to :class:`CellController`), set up and in Idle,
    and its control loop."""
    kw.setdefault("wait_for_unhold", True)  # the controller's own default
    assembled = assemble_cell(
        cell, tasks, backend, journal=Journal(":memory:"), use_cache=False, **kw
    ).setup()
    assembled.loop.step(3)
    return assembled.controller, assembled.loop
