"""The wrist force/torque sensor of the twin, read as UR's controller reports it: the
external wrench on the tool in base axes, torque about the flange, payload compensated,
minus the offset of the last zeroing."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cellrunner.sim.model_ids import ModelIds

GRAVITY_MPS2 = 9.81


class WristSensor:
    """Reads MuJoCo's ``ft_force``/``ft_torque`` sensors of one built model ``data``.

    ``tool_weight_N``: the payload's weight the controller compensates (setPayload)."""

    def __init__(self, data: Any, ids: ModelIds, T_world_base: np.ndarray) -> None:
        # views into MjData (its buffers never move)
        self._R_site_flat = data.site_xmat[ids.ft_site]  # row-major 3x3
        self._ft_flat = data.sensordata[ids.force_adr : ids.force_adr + 6]  # force, torque
        self._tool_com = data.subtree_com[ids.tool_body]
        self._site_pos = data.site_xpos[ids.ft_site]
        R_world_base = np.array(T_world_base[:3, :3], dtype=float)
        self._R_base_world_flat = tuple(R_world_base.T.ravel().tolist())
        self.tool_weight_N = GRAVITY_MPS2 * ids.tool_mass_kg
        self._offset: tuple[float, ...] = (0.0,) * 6

    def zero(self) -> None:
        """Take the present reading as zero (zero_ftsensor)."""
        self._offset = tuple(self.raw_wrench_base())

    def wrench(self) -> np.ndarray:
        """(fx, fy, fz, tx, ty, tz) in N and N m, base axes, less the zeroing offset."""
        w = self.raw_wrench_base()
        o0, o1, o2, o3, o4, o5 = self._offset
        return np.array((w[0] - o0, w[1] - o1, w[2] - o2, w[3] - o3, w[4] - o4, w[5] - o5))

    def raw_wrench_base(self) -> list[float]:
        """External wrench on the tool (payload compensated), base axes, torque at flange:
        (fx, fy, fz, tx, ty, tz) in N and N m.

        MuJoCo's force/torque sensors give the force and torque the flange exerts on the
        tool subtree (tool, fingers, anything they hold), in the ``ft`` site frame. In
        static balance the external wrench is minus that, minus the tool's own weight
        (the configured payload, which UR's controller also compensates). Plain float
        arithmetic: numpy's per-call cost dwarfs 3x3 products, and this runs every period.
        """
        return self.external_wrench(
            self._ft_flat.tolist(),
            self._R_site_flat.tolist(),
            self._tool_com.item(0),
            self._tool_com.item(1),
            self._site_pos.item(0),
            self._site_pos.item(1),
        )

    def wrench_from(
        self, ft: Sequence[Any], R_site: Sequence[Any], cx: Any, cy: Any, sx: Any, sy: Any
    ) -> np.ndarray:
        """:meth:`wrench` (rows: periods) from recorded readings, each an array over
        periods: ``ft`` the sensed (fx, fy, fz, tx, ty, tz), ``R_site`` the ``ft`` site's
        rotation row-major, ``cx, cy`` the tool's centre of mass and ``sx, sy`` the site
        (world x, y). The same operations in the same order as :meth:`wrench`, element
        by element, so each row equals what :meth:`wrench` read in that period."""
        w = self.external_wrench(ft, R_site, cx, cy, sx, sy)
        return np.stack([w[i] - self._offset[i] for i in range(6)], axis=1)

    def external_wrench(
        self, ft: Sequence[Any], R_site: Sequence[Any], cx: Any, cy: Any, sx: Any, sy: Any
    ) -> list[Any]:
        """The arithmetic of :meth:`raw_wrench_base`, on floats or on arrays alike."""
        fx, fy, fz, tx, ty, tz = ft
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R_site
        mg = self.tool_weight_N
        # world axes: minus the sensed wrench (site -> world), minus the tool's weight
        # (0, 0, -mg) and its moment about the flange, (c - s) x (0, 0, -mg)
        ex = -(r00 * fx + r01 * fy + r02 * fz)
        ey = -(r10 * fx + r11 * fy + r12 * fz)
        ez = mg - (r20 * fx + r21 * fy + r22 * fz)
        mx = mg * (cy - sy) - (r00 * tx + r01 * ty + r02 * tz)
        my = -mg * (cx - sx) - (r10 * tx + r11 * ty + r12 * tz)
        mz = -(r20 * tx + r21 * ty + r22 * tz)
        b00, b01, b02, b10, b11, b12, b20, b21, b22 = self._R_base_world_flat
        return [
            b00 * ex + b01 * ey + b02 * ez,
            b10 * ex + b11 * ey + b12 * ez,
            b20 * ex + b21 * ey + b22 * ez,
            b00 * mx + b01 * my + b02 * mz,
            b10 * mx + b11 * my + b12 * mz,
            b20 * mx + b21 * my + b22 * mz,
        ]
