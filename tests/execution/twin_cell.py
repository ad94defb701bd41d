"""The real cell controller on a MuJoCo twin backend, in this process, for tests that
drive jobs period by period."""

from __future__ import annotations

from typing import Any

from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner
from cellrunner.model.load import LoadedCell
from cellrunner.planning.world import CellWorld


def twin_cell(
    cell: LoadedCell, tasks: dict[int, Any], backend: Any, **kw: Any
) -> tuple[CellController, ControlLoop]:
    """The controller of ``cell`` running ``tasks`` on ``backend`` (planned afresh, no plan
    cache; an in-memory journal; ``kw`` to :class:`CellController`), set up and in Idle,
    and its control loop."""
    planner = job_planner(CellWorld(cell), use_cache=False)
    controller = CellController(cell, tasks, backend, Journal(":memory:"), planner, **kw)
    controller.setup()
    loop = ControlLoop(controller)
    loop.step(3)
    return controller, loop
