"""Choosing and building the robot backend a cell runs on (``robot.backend``, overridden
by ``--backend`` and ``--robot-host``). Imports are lazy: mujoco or ur_rtde load only
for the backend in use."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from cellrunner.backends.base import RobotBackend
from cellrunner.errors import UsageError
from cellrunner.model.load import LoadedCell, LoadedTask


def backend_kind(cell: LoadedCell, override: str | None) -> str:
    return override or cell.cell.robot.backend


def make_backend(
    cell: LoadedCell,
    kind: str,
    host: str | None = None,
    tasks: Iterable[LoadedTask] = (),
    rehearsed: Sequence[dict[str, Any]] = (),
    **kw: Any,
) -> RobotBackend:
    """The backend for ``cell``: ``sim`` (the MuJoCo twin in-process, its parts laid as
    the tools that pick them in ``tasks`` and the cell's own tasks hold them) or ``ur``.
    ``rehearsed`` (sim, a dry-run's jobs' params in order): the twin of their rehearsal
    with the first of ``tasks``, the earlier slots of the first job filled and, for
    several jobs, a part fed before each (SPEC section 12)."""
    if kind == "sim":
        from cellrunner.backends.sim.backend import SimBackend
        from cellrunner.sim.from_cell import description_of, rehearsal_description

        if rehearsed:
            task = next(iter(tasks))
            return SimBackend(rehearsal_description(cell, task, rehearsed[0], len(rehearsed)), **kw)
        return SimBackend(description_of(cell, tuple(tasks)), **kw)
    if kind == "ur":
        host = host or cell.cell.robot.host
        if not host:
            raise UsageError(
                "the ur backend needs a controller address: robot.host in the cell file or --robot-host"
            )
        from cellrunner.backends.ur import URBackend
        from cellrunner.model.geometry import tcp_pose_of

        c = cell.cell
        g = c.tool.gripper
        robotiq = g.port if g is not None and g.kind == "robotiq" and g.close is None else None
        return URBackend(
            host,
            cell.spec,
            tcp_pose=tcp_pose_of(c.tool.tcp.matrix()),
            payload_kg=c.tool.payload.mass,
            payload_cog_m=c.tool.payload.cog_m,
            robotiq_port=robotiq,
            conveyors=dict(c.conveyors),
            **kw,
        )
    raise UsageError(f"unknown backend {kind!r}; known: ur, sim")
