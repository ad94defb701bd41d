"""The line around the sim backend's twin: its belts (encoder travel, speed, encoder
faults) and its intruders (started with a job, dropped by ``--inject intrusion``). The
backend's methods of the same names call these on its world."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import BackendError

if TYPE_CHECKING:
    from cellrunner.sim.belts import Belts
    from cellrunner.sim.world import SimWorld


def conveyor_travel_m(world: SimWorld, name: str) -> float | None:
    """See :meth:`.backend.SimBackend.conveyor_travel_m`."""
    belts = world.belts
    if belts is None or name not in belts.descs:
        return None
    return belts.travel_m(name)


def belts_of(world: SimWorld, name: str) -> Belts:
    """The world's belts; raises BackendError when it has none (naming belt ``name``)."""
    belts = world.belts
    if belts is None:
        raise BackendError(f"the twin has no belt {name!r}")
    return belts


def job_started(world: SimWorld) -> None:
    """See :meth:`.backend.SimBackend.job_started`."""
    if world.intruders is not None:
        world.intruders.start(world.time_s)


def inject_intrusion(world: SimWorld, T_world_box: np.ndarray) -> str | None:
    """See :meth:`.backend.SimBackend.inject_intrusion`."""
    if world.intruders is None:
        return None
    return world.intruders.inject(T_world_box, world.time_s)
