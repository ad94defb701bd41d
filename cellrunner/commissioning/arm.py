"""Reading where the arm stands, through ur_rtde's receive interface only (nothing is
uploaded to the controller, so a program or the pendant keeps control of the arm).

Poses come from the measured joint angles and the cell's own kinematics: the mount puts
the controller's base frame in the world and the cell's ``tool.tcp`` puts the TCP on the
flange, so a taught pose is exactly what planning will aim at, whatever TCP the pendant
has set.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from cellrunner.errors import PeerUnreachable
from cellrunner.model.load import LoadedCell

#: joint readings averaged per pose (at the controller rate; damps measurement noise)
SAMPLES_PER_POSE = 25
#: the arm must stand still while a pose is read: max joint speed, rad/s
STILL_RAD_S = 1e-3


class ArmReader:
    """Measured joint angles of the arm at ``host``; ``connect`` before reading."""

    def __init__(self, cell: LoadedCell, host: str, connect_timeout_s: float = 3.0) -> None:
        self.cell, self.host, self.connect_timeout_s = cell, host, connect_timeout_s
        self._receive: Any = None  # ur_rtde's RTDEReceiveInterface (untyped bindings)

    def connect(self) -> None:
        from cellrunner.backends.ur_probe import controller_version

        controller_version(self.host, self.connect_timeout_s)  # fails fast (ur_rtde would wait)
        import rtde_receive

        try:
            self._receive = rtde_receive.RTDEReceiveInterface(
                self.host, self.cell.spec.rate_hz, ["timestamp", "actual_q", "actual_qd"]
            )
        except (RuntimeError, OSError) as exc:
            raise PeerUnreachable(f"cannot read the arm at {self.host}: {exc}") from exc

    def close(self) -> None:
        if self._receive is not None:
            self._receive.disconnect()
            self._receive = None

    def read_q_rad(self, samples: int = SAMPLES_PER_POSE, timeout_s: float = 5.0) -> np.ndarray:
        """The mean of ``samples`` joint readings taken while the arm stands still (rad)."""
        period_s = 1.0 / self.cell.spec.rate_hz
        readings: list[list[float]] = []
        deadline = time.monotonic() + timeout_s
        while len(readings) < samples:
            if time.monotonic() > deadline:
                raise PeerUnreachable(
                    f"the arm at {self.host} did not stand still for a reading "
                    f"within {timeout_s:g} s"
                )
            if not self._receive.isConnected():
                raise PeerUnreachable(f"lost the connection to the arm at {self.host}")
            if max(abs(v) for v in self._receive.getActualQd()) > STILL_RAD_S:
                readings.clear()
            else:
                readings.append(list(self._receive.getActualQ()))
            time.sleep(period_s)
        return np.asarray(np.mean(np.array(readings), axis=0))
