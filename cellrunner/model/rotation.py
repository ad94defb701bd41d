"""XYZ fixed-axis (roll, pitch, yaw) rotations in plain Python: what the load-time checks
need without numpy (``validate`` never imports it); :mod:`.geometry` builds its matrices
from the same rows."""

from __future__ import annotations

import math
from collections.abc import Iterable


def rpy_rows(rpy_deg: Iterable[float]) -> list[list[float]]:
    """Rows of the rotation of XYZ fixed-axis roll, pitch, yaw in degrees: Rz @ Ry @ Rx."""
    r, p, y = (math.radians(float(v)) for v in rpy_deg)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
