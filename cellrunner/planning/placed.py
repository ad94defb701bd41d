"""The parts a job finds or leaves set down: obstacles to every step after them, supports
to a place onto them (issue 33).

- A place's release leaves its part where it was let go (``placed:NAME@STEP``; the
  release checks that it rests there, :mod:`.support`).
- Not yet: the parts earlier jobs left on a pattern's earlier slots (the twin spawns
  them, sim/feed) as obstacles; they are supports only (:mod:`.support`). Planned
  around, they moved the pattern's joint paths, one of which then failed verification
  by a hair (issue 33, docs/check-truth.md).

The planner's world carries them (:meth:`CellWorld.with_placed
<cellrunner.planning.world.CellWorld.with_placed>`) as parts lying in the cell, beside the
waiting ones: a grip's jaws may leave one they let go, a later place may come down onto
one, and every other move keeps the cell's clearance from them.
"""

from __future__ import annotations

import numpy as np

from cellrunner.model.body import PLACED_PREFIX
from cellrunner.model.geometry import Placed


def placed_part(part: Placed, T_world_part: np.ndarray, where: str) -> Placed:
    """The carried ``part`` set down at ``T_world_part``, named ``placed:NAME@WHERE``."""
    return Placed(f"{PLACED_PREFIX}{part.name}@{where}", part.shape, T_world_part)
