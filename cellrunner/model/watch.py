"""The watched zone (``watch:``, SPEC section 12): which depth cameras feed the live obstacle
map, the volume it covers, its leaf size, OctoMap's per-observation probabilities and the
padding everything the cell file explains keeps.

```yaml
watch:
  cameras: [overhead]
  zone: {box: {size: [1.6, 1.2, 1.0]}, pose: {xyz: [0.4, 0, 1.4]}}
  voxel: 0.02
  occupancy: {hit: 0.7, miss: 0.4}
  padding: 0.03
```

Pure data; :func:`cellrunner.model.checks.check_watch` reports, located, what refers to the rest of the cell.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import BoxShape, Name, Pose, Strict
from cellrunner.model.units import NonNegativeLength, PositiveLength

#: the map covers at most this many voxels (a dense table of log-odds, 4 bytes each)
MAX_VOXELS = 16_000_000


#: the box ``--inject intrusion@STEP`` drops onto a step's path in the twin (m): the twin
#: builds it and the rehearsal finds room for it on the path
INJECTED_BOX_M = (0.12, 0.12, 0.12)


class Zone(Strict):
    """The watched volume: a box placed in the world."""

    box: BoxShape
    """Edge lengths along the zone's x, y, z in m. Example: `{size: [1.6, 1.2, 1.0]}`"""
    pose: Pose = Field(default_factory=Pose)
    """The box's centre and orientation in the world, m and deg. Example: `{xyz: [0.4, 0, 1.4]}`"""


class Occupancy(Strict):
    """OctoMap's sensor model: the probability one observation gives a voxel it ends in
    (``hit``) and one it passes through (``miss``)."""

    hit: float = Field(default=0.7, gt=0.5, lt=1.0)
    """Occupancy probability of a voxel a depth ray ends in. Example: `0.7`"""
    miss: float = Field(default=0.4, gt=0.0, lt=0.5)
    """Occupancy probability of a voxel a depth ray passes through. Example: `0.4`"""


class Watch(Strict):
    """Depth cameras that feed a live obstacle map of a zone of the cell."""

    cameras: Annotated[list[Name], Field(min_length=1)]
    """Depth cameras (from `cameras:`, each with `depth:`) that feed the map. Example: `[overhead]`"""
    zone: Zone
    """Only this volume is watched: points outside it are dropped. Example: `{box: {size: [1.6, 1.2, 1.0]}, pose: {xyz: [0.4, 0, 1.4]}}`"""
    voxel: PositiveLength = Field(default=0.02)
    """Leaf size of the map, m. Example: `0.02`"""
    occupancy: Occupancy = Field(default_factory=Occupancy)
    """Per-observation update probabilities (OctoMap's model). Example: `{hit: 0.7, miss: 0.4}`"""
    padding: NonNegativeLength = 0.03
    """Distance the arm, tool and held part keep from any occupied voxel, and by which what the cell file explains is grown before it is filtered out, m. Example: `0.03`"""

    @model_validator(mode="after")
    def _sizes(self) -> Watch:
        if not 0.002 <= self.voxel <= 0.25:
            raise PydanticCustomError("watch", f"voxel {self.voxel:g} m is outside [0.002, 0.25] m")
        n = math.prod(math.ceil(s / self.voxel) for s in self.zone.box.size)
        if n > MAX_VOXELS:
            raise PydanticCustomError(
                "watch",
                f"a {' x '.join(f'{s:g}' for s in self.zone.box.size)} m zone in "
                f"{self.voxel:g} m voxels has {n:,} of them; the map holds at most "
                f"{MAX_VOXELS:,} (a larger voxel, or a smaller zone)",
            )
        return self
