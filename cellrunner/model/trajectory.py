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

from cellrunner.errors import InternalError

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
            # ValueError, as numpy's own for arrays that do not fit: the plan store reads
            # stored arrays through here and drops a file whose shapes are wrong
            raise ValueError(f"trajectory shapes t{self.t_s.shape} q{self.q_rad.shape}")

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0

    @property
    def qd_rad_s(self) -> np.ndarray:
        """Joint speeds by finite differences (N x 6), zero at the ends' outside."""
        if len(self.q_rad) < 2:
            return np.zeros_like(self.q_rad)
        qd: np.ndarray = np.gradient(self.q_rad, 1.0 / self.rate_hz, axis=0)
        return qd

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


def time_scaled(approved: ApprovedTrajectory, speed: float) -> ApprovedTrajectory:
    """The approved trajectory at ``speed`` x its pace (0 < speed <= 1): the same joint
    path, stretched in time only, resampled at the same controller rate.

    Set-point ``k / speed`` is approved sample ``k`` exactly whenever ``k / speed`` is an
    integer (every 4th set-point at 0.25); the set-points between lie on the straight
    joint-space segment between two approved samples, which is what the controller
    interpolates anyway. Joint speeds scale by ``speed``; nothing leaves the approved path,
    so the result keeps the approval (sealed here, from a sealed input only).
    """
    if not approved.is_sealed:
        raise InternalError("only an approved (sealed) trajectory can be time-scaled")
    if not 0.0 < speed <= 1.0:
        raise InternalError(f"speed {speed:g} is outside (0, 1]: a fraction of the approved pace")
    source = approved.trajectory
    if speed == 1.0 or len(source.q_rad) < 2:
        return approved
    last = len(source.q_rad) - 1
    n = int(np.ceil(last / speed - 1e-9)) + 1
    u = np.minimum(np.arange(n) * speed, last)  # position along the source, in samples
    i = np.minimum(np.floor(u + 1e-9).astype(int), last)
    frac = np.clip(u - i, 0.0, 1.0)[:, None]
    j = np.minimum(i + 1, last)
    q = source.q_rad[i] + frac * (source.q_rad[j] - source.q_rad[i])
    exact = frac[:, 0] < 1e-9
    q[exact] = source.q_rad[i[exact]]  # approved samples pass through bit for bit
    scaled = Trajectory(source.rate_hz, source.t_s[0] + np.arange(n) / source.rate_hz, q)
    return approve(scaled, approved.step_index, approved.step_name)


def backwards(approved: ApprovedTrajectory, i_from: int, i_to: int) -> ApprovedTrajectory:
    """Set-points ``i_from`` down to ``i_to`` of the approved trajectory, streamed in that
    order (a guarded line going back to where its contact began): the same approved
    samples, so the same path, speeds and accelerations mirrored in time; it keeps the
    approval. Streamed as its own trajectory, its speeds point back along the line (the
    forward trajectory's, sent in reverse, push the tool into what it touched)."""
    if not approved.is_sealed:
        raise InternalError("only an approved (sealed) trajectory can be run backwards")
    source = approved.trajectory
    if not 0 <= i_to <= i_from < len(source.q_rad):
        raise InternalError(f"set-points {i_from}..{i_to} are outside 0..{len(source.q_rad) - 1}")
    q = source.q_rad[i_to : i_from + 1][::-1].copy()
    back = Trajectory(source.rate_hz, source.t_s[0] + np.arange(len(q)) / source.rate_hz, q)
    return approve(back, approved.step_index, approved.step_name)


def along_path(approved: ApprovedTrajectory, u: np.ndarray) -> ApprovedTrajectory:
    """The approved path followed at other speeds: set-point ``k`` is the approved path at
    sample position ``u[k]`` (fractional, non-decreasing, within the trajectory), linear
    between two approved samples as :func:`time_scaled` does. A stop on the path (``u``
    slowing to a standstill) and a restart from it are built this way; nothing leaves the
    approved path, so the result keeps the approval (sealed here, from a sealed input only).
    The caller keeps the speeds and accelerations that ``u`` implies within the limits."""
    if not approved.is_sealed:
        raise InternalError("only an approved (sealed) trajectory can be followed along its path")
    source = approved.trajectory
    last = len(source.q_rad) - 1
    u = np.asarray(u, float)
    if not len(u) or np.any(np.diff(u) < -1e-12) or u[0] < -1e-9 or u[-1] > last + 1e-9:
        raise InternalError(f"path positions must rise within [0, {last}]")
    u = np.clip(u, 0.0, last)
    i = np.minimum(np.floor(u + 1e-9).astype(int), last)
    frac = np.clip(u - i, 0.0, 1.0)[:, None]
    j = np.minimum(i + 1, last)
    q = source.q_rad[i] + frac * (source.q_rad[j] - source.q_rad[i])
    exact = frac[:, 0] < 1e-9
    q[exact] = source.q_rad[i[exact]]
    followed = Trajectory(source.rate_hz, source.t_s[0] + np.arange(len(u)) / source.rate_hz, q)
    return approve(followed, approved.step_index, approved.step_name)
