"""A recorder on an assembled cell: the twin's own model and state when the backend is
the twin, else the twin's model of the cell posed by the measured joints."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.record.collector import Collector
from cellrunner.record.files import warm_up
from cellrunner.record.sink import Sink

if TYPE_CHECKING:
    from cellrunner.execution.assembly import AssembledCell
    from cellrunner.record.scene import SceneModel


def record_cell(
    assembled: AssembledCell,
    open_sink: Callable[[str], Sink],
    suffix: str,
    *,
    per_job: bool = False,
) -> Collector:
    """A :class:`Collector` on ``assembled``'s loop (added as its observer); ``close()`` it
    after the loop stopped."""
    loaded = assembled.loaded
    twin: Any = getattr(assembled.backend, "world", None)  # the sim backend's SimWorld

    def qpos_of() -> np.ndarray | None:
        data = getattr(twin, "data", None)
        return None if data is None else np.array(data.qpos)

    def scene_of() -> SceneModel:
        from cellrunner.record.scene import SceneModel

        if twin is not None and twin.model is not None:
            return SceneModel(twin.model)
        from cellrunner.sim.from_cell import description_of
        from cellrunner.sim.mjcf import compile_model

        return SceneModel(compile_model(description_of(loaded)))

    obstacles_of = depth_of = None
    zone = assembled.watch
    if zone is not None:

        def obstacles_of() -> np.ndarray | None:
            return zone.map.occupied_centres()

        def depth_of() -> dict[str, Any]:
            return dict(zone.last_frames)

    pictures_of = None
    eye: Any = assembled.controller.eye
    if eye is not None and hasattr(eye, "last_pictures"):  # the cameras align steps look through

        def pictures_of() -> dict[str, np.ndarray]:
            return dict(eye.last_pictures)

    io = loaded.cell.io
    collector = Collector(
        scene_of,
        open_sink,
        {**io.outputs, **io.inputs},
        qpos_of=qpos_of if twin is not None else None,
        obstacles_of=obstacles_of,
        depth_of=depth_of,
        pictures_of=pictures_of,
        per_job=per_job,
        warm_up=lambda: warm_up(suffix),
    )
    assembled.loop.add_observer(collector)
    return collector


def record_to_file(assembled: AssembledCell, target: Path) -> Collector:
    """``--record FILE`` of ``dry-run`` and ``run``: the whole run in one file."""
    from cellrunner.record.files import open_sink

    name = assembled.loaded.cell.cell
    return record_cell(assembled, lambda job_id: open_sink(target, name), target.suffix)


def finish(collector: Collector, target: Path) -> str:
    """Close ``collector``; the line to print about what it wrote."""
    collector.close()
    if collector.error is not None:
        return f"recording {target} stopped early: {collector.error}"
    dropped = f", {collector.dropped} dropped" if collector.dropped else ""
    return f"recorded {collector.written} samples to {target}{dropped}"


def record_jobs(assembled: AssembledCell, folder: Path, suffix: str, max_mb: float) -> Collector:
    """``serve --record DIR``: each job in its own file (:class:`~.files.JobFolder`)."""
    from cellrunner.record.files import JobFolder

    return record_cell(assembled, JobFolder(folder, max_mb, suffix).open, suffix, per_job=True)
