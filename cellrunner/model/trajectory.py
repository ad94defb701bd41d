"""Joint trajectories sampled at the controller rate, and their approval seal.

A :class:`Trajectory` is pure data. Only the final verification pass of planning turns
one into an :class:`ApprovedTrajectory` (through :func:`approve`), and backends accept
nothing else: this is how "no trajectory reaches a backend that `check` did not approve"
is kept by construction rather than by convention.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass, field

import numpy as np

# A per-process secret: an ApprovedTrajectory cannot be forged by building one by hand
# (the seal would not match), only by calling approve() -- which planning's verifier does.
_SEAL_KEY = secrets.token_bytes(16)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Joint positions ``q_rad`` (N x 6) at times ``t_s`` (N), every 1/rate_hz seconds."""

    rate_hz: float
    t_s: np.ndarray
    q_rad: np.ndarray

    def __post_init__(self) -> None:
        for name in ("t_s", "q_rad"):
            array = np.array(getattr(self, name), dtype=float)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        if self.q_rad.ndim != 2 or self.q_rad.shape[1] != 6 or len(self.t_s) != len(self.q_rad):
            raise ValueError(f"trajectory shapes t{self.t_s.shape} q{self.q_rad.shape}")

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0

    @property
    def qd_rad_s(self) -> np.ndarray:
        """Joint speeds by finite differences (N x 6), zero at the ends' outside."""
        if len(self.q_rad) < 2:
            return np.zeros_like(self.q_rad)
        return np.gradient(self.q_rad, 1.0 / self.rate_hz, axis=0)

    def digest(self) -> str:
        h = hashlib.sha256()
        h.update(np.float64(self.rate_hz).tobytes())
        h.update(np.ascontiguousarray(self.q_rad).tobytes())
        return h.hexdigest()


@dataclass(frozen=True, eq=False)
class ApprovedTrajectory:
    """A trajectory that passed the final independent check; backends stream only these."""

    trajectory: Trajectory
    step_index: int
    step_name: str
    _seal: str = field(repr=False, default="")

    @property
    def is_sealed(self) -> bool:
        return secrets.compare_digest(self._seal, _seal_of(self.trajectory))


def _seal_of(trajectory: Trajectory) -> str:
    return hashlib.sha256(_SEAL_KEY + trajectory.digest().encode()).hexdigest()


def approve(trajectory: Trajectory, step_index: int, step_name: str) -> ApprovedTrajectory:
    """Seal ``trajectory``; call only from the verifier after every check has passed."""
    return ApprovedTrajectory(trajectory, step_index, step_name, _seal_of(trajectory))
