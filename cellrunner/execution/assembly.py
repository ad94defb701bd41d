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

from cellrunner.backends.base import CameraImages, FeedsParts, RobotBackend
from cellrunner.execution.cell import CellController
from cellrunner.execution.context import EventLog, Eye
from cellrunner.execution.journal import JournalBackend
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner, warm_up
from cellrunner.model.expand import Step
from cellrunner.model.load import LoadedCell, LoadedTask

if TYPE_CHECKING:
    from cellrunner.execution.watch import SourceDepthFeed, TwinDepthFeed, ZoneWatch
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
    feed: TwinDepthFeed | SourceDepthFeed | None = None  # depth images into it (an observer)

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
    kind: str = "",
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
    image_source: str | None = None,
    watched: bool = False,
    depth_source: str | None = None,
) -> AssembledCell:
    """The cell ``loaded`` running ``tasks`` (PLC task number -> task).

    ``backend`` is a kind (``sim``: the MuJoCo twin in this process, built with the parts
    of ``tasks``; ``ur``: the arm at ``robot_host`` or the cell's ``robot.host``) or a
    backend already built (``kind`` says which, e.g. ``sim`` for a twin with its own
    description). ``journal`` defaults to the one the cell file names. ``warm``
    loads the planning stack and builds the cell's models now (serve, before READY).
    ``use_cache``, ``speed`` and ``joined`` go to the job planner
    (:func:`~cellrunner.execution.planner.job_planner`); ``log``, ``wait_for_unhold``,
    ``on_step_start`` and ``gate`` to the controller; ``feed_parts`` lets the twin's
    infeed bring a part at each job's start; ``realtime`` and ``lookahead`` to the loop.
    ``eye``: align steps see through the cell's cameras (rendered by the in-process
    twin; on the arm from ``image_source``, default the cameras of a ``cellrunner twin``
    at the robot's host); ``watched``: a cell with ``watch:`` checks every motion against
    its zone's map, fed by the twin's depth cameras (``sim``) or, on the arm, by
    ``depth_source`` (default: the virtual controller's at the robot's host). The feed is
    one of the loop's observers; ``start()`` it once the robot is connected."""
    from cellrunner.planning.world import CellWorld

    if isinstance(backend, str):
        from cellrunner.backends.factory import make_backend

        kind, backend = backend, make_backend(loaded, backend, robot_host, tasks=tasks.values())
    if journal is None:
        from cellrunner.execution.journal_open import cell_journal

        journal = cell_journal(loaded)
    world = CellWorld(loaded)
    if warm:
        warm_up(world)
    zone, feed = (
        _watch(world, backend, realtime, depth_source, robot_host or loaded.cell.robot.host, log)
        if watched and kind
        else (None, None)
    )
    controller = CellController(
        loaded,
        tasks,
        backend,
        journal,
        job_planner(world, use_cache=use_cache, speed=speed, joined=joined),
        log=log,
        wait_for_unhold=wait_for_unhold,
        on_step_start=on_step_start,
        on_job_start=_infeed(backend) if feed_parts else None,
        gate=gate,
        eye=_eye(loaded, backend, image_source, robot_host) if eye else None,
        watch=zone,
    )
    loop = ControlLoop(controller, realtime=realtime, lookahead=lookahead)
    if feed is not None:
        loop.add_observer(feed)
    return AssembledCell(loaded, world, backend, kind, journal, controller, loop, zone, feed)


def _watch(
    world: CellWorld,
    backend: RobotBackend,
    realtime: bool,
    depth_source: str | None,
    host: str | None,
    log: EventLog | None,
) -> tuple[ZoneWatch | None, TwinDepthFeed | SourceDepthFeed | None]:
    """The watched zone's map and its depth feed (:func:`~cellrunner.execution.watch.watch_cell`),
    (None, None) for a cell without ``watch:``."""
    from cellrunner.execution.watch import watch_cell

    found = watch_cell(
        world, backend, realtime=realtime, depth_source=depth_source, host=host, log=log
    )
    return (None, None) if found is None else found


def _infeed(backend: RobotBackend) -> Callable[[], None] | None:
    """The backend's own infeed, run at each job's start (the twin's ``sim: feed``); None
    for a backend without one (the arm: the cell's conveyor runs on its own)."""
    if not isinstance(backend, FeedsParts):
        return None
    feeder = backend

    def feed() -> None:
        feeder.feed_parts()

    return feed


def _eye(
    loaded: LoadedCell, backend: RobotBackend, image_source: str | None, host: str | None
) -> Eye | None:
    """The cameras an align step sees through: the in-process twin renders them (``sim``);
    on the arm (``ur``) pictures come from ``image_source`` (default: the cameras of a
    ``cellrunner twin`` at ``host``). None for a cell without cameras."""
    if not loaded.cell.cameras:
        return None
    from cellrunner.vision.eye import MarkerEye

    if isinstance(backend, CameraImages):
        grab = backend.camera_image
    else:
        from cellrunner.vision.images import CameraFeeds

        feeds = CameraFeeds(image_source, dict(loaded.cell.cameras), host or loaded.cell.robot.host)
        grab = feeds.grab
    return MarkerEye(grab, dict(loaded.cell.cameras))
