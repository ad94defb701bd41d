"""The one place that assembles a cell to run jobs on: the planning world, the robot
backend, the journal, the job planner, the cell controller and its control loop.

``run``, ``dry-run``, ``serve``, ``calibrate-camera`` and the benches all build their
cell here, so a change to how a cell is put together is made once. Nothing here
connects: :meth:`AssembledCell.setup` opens the journal and connects the robot (STYLE
rule 4), :meth:`AssembledCell.close` lets go of both.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cellrunner.backends.base import RobotBackend
from cellrunner.execution.cell import CellController
from cellrunner.execution.context import EventLog, Eye
from cellrunner.execution.journal import JournalBackend
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner, warm_up
from cellrunner.model.expand import Step
from cellrunner.model.load import LoadedCell, LoadedTask

if TYPE_CHECKING:
    from cellrunner.execution.watch import ZoneWatch
    from cellrunner.planning.world import CellWorld


@dataclass(frozen=True)
class AssembledCell:
    """A cell put together and not yet connected (:meth:`setup` connects it)."""

    loaded: LoadedCell
    world: CellWorld
    backend: RobotBackend
    backend_kind: str  # "sim" or "ur"; "" when the caller handed in its own backend
    journal: JournalBackend
    controller: CellController
    loop: ControlLoop
    watch: ZoneWatch | None = None  # the watched zone's map (a cell with watch:)

    def setup(self) -> AssembledCell:
        """Open the journal, connect the robot, reset to Idle."""
        self.controller.setup()
        return self

    def close(self) -> None:
        self.controller.close()


def assemble_cell(
    loaded: LoadedCell,
    tasks: dict[int, LoadedTask],
    backend: str | RobotBackend,
    *,
    robot_host: str | None = None,
    journal: JournalBackend | None = None,
    warm: bool = False,
    use_cache: bool = True,
    speed: float = 1.0,
    joined: bool = True,
    log: EventLog | None = None,
    wait_for_unhold: bool = False,
    feed_parts: bool = False,
    on_step_start: Callable[[Step, int], None] | None = None,
    gate: Callable[[Step], bool] | None = None,
    realtime: bool = False,
    lookahead: bool = True,
    eye: bool = False,
    watched: bool = False,
) -> AssembledCell:
    """The cell ``loaded`` running ``tasks`` (PLC task number -> task).

    ``backend`` is a kind (``sim``: the MuJoCo twin in this process, built with the parts
    of ``tasks``; ``ur``: the arm at ``robot_host`` or the cell's ``robot.host``) or a
    backend already built. ``journal`` defaults to the one the cell file names. ``warm``
    loads the planning stack and builds the cell's models now (serve, before READY).
    ``use_cache``, ``speed`` and ``joined`` go to the job planner
    (:func:`~cellrunner.execution.planner.job_planner`); ``log``, ``wait_for_unhold``,
    ``on_step_start`` and ``gate`` to the controller; ``feed_parts`` lets the twin's
    infeed bring a part at each job's start; ``realtime`` and ``lookahead`` to the loop.
    ``eye``: align steps see through the cameras the backend renders (the in-process
    twin's); ``watched``: a cell with ``watch:`` checks every motion against its zone's
    map (:class:`~cellrunner.execution.watch.ZoneWatch`, fed by the caller)."""
    from cellrunner.planning.world import CellWorld

    kind = ""
    if isinstance(backend, str):
        from cellrunner.backends.factory import make_backend

        kind, backend = backend, make_backend(loaded, backend, robot_host, tasks=tasks.values())
    if journal is None:
        from cellrunner.execution.journal_open import cell_journal

        journal = cell_journal(loaded)
    world = CellWorld(loaded)
    if warm:
        warm_up(world)
    zone = None
    if watched and loaded.cell.watch is not None:
        from cellrunner.execution.watch import ZoneWatch

        zone = ZoneWatch(world, loaded.cell.watch)
    controller = CellController(
        loaded,
        tasks,
        backend,
        journal,
        job_planner(world, use_cache=use_cache, speed=speed, joined=joined),
        log=log,
        wait_for_unhold=wait_for_unhold,
        on_step_start=on_step_start,
        on_job_start=getattr(backend, "feed_parts", None) if feed_parts else None,
        gate=gate,
        eye=_twin_eye(loaded, backend) if eye else None,
        watch=zone,
    )
    loop = ControlLoop(controller, realtime=realtime, lookahead=lookahead)
    return AssembledCell(loaded, world, backend, kind, journal, controller, loop, zone)


def _twin_eye(loaded: LoadedCell, backend: RobotBackend) -> Eye | None:
    """The cameras an align step sees through: rendered by the in-process twin (``sim``
    backend), None for a cell without cameras or a backend that renders none."""
    grab = getattr(backend, "camera_image", None)
    if not loaded.cell.cameras or grab is None:
        return None
    from cellrunner.vision.eye import MarkerEye

    return MarkerEye(grab, dict(loaded.cell.cameras))
