"""The live obstacle map of the watched zone: log-odds occupancy per voxel, OctoMap's
sensor model (SPEC section 12).

Storage. The zone is a bounded box, so its voxels are addressed directly: a point's voxel
is its linear index in the zone's grid (a perfect hash: no collisions, no sort), and the
map is one float32 table of log-odds over them (4 bytes a voxel: 1 MB for a 1.6 x 1.2 x
1.0 m zone at 2 cm). Counting the points per voxel is one ``bincount`` (O(points +
voxels)), never ``np.unique`` over every point.

Update (:meth:`OccupancyMap.integrate`), per depth image:

1. back-project the pixels with a depth in the camera's range; keep the points in the zone;
2. hits: voxels holding at least ``MIN_POINTS`` points (a lone flying pixel is an
   outlier), less those the cell file explains (:mod:`.known`: the static table, then the
   robot's solids at the measured configuration);
3. misses: free space along each ray, projectively: every voxel of the zone is projected
   into the image once per camera pose; a voxel whose far corner lies in front of the
   depth its pixel measured was passed through (MoveIt's depth-image updater does the same);
   a voxel that got a hit in this image gets no miss;
4. log-odds += logit(hit) or logit(miss), clamped to [logit(FREE_CLAMP), logit(0.97)].

A voxel is occupied while its log-odds is above 0 (p > 0.5). Free space keeps at most one
miss of evidence (``FREE_CLAMP`` = the miss probability): one image in which rays end in
a voxel makes it occupied, so an intruder is seen in the first image that shows it, and
a voxel seen free again for about nine images (0.6 s at 15 Hz) after being fully
occupied is cleared.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cellrunner.errors import UsageError
from cellrunner.perception.frames import DepthFrame, RayTable

#: a voxel needs this many points of one image to count as hit (fewer: outliers)
MIN_POINTS = 3
#: occupancy is clamped to at most this probability (OctoMap's default)
OCCUPIED_CLAMP = 0.97


def logit(p: float) -> float:
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class MapUpdate:
    """What one image did: its camera and time, the voxels it hit and cleared, how many
    are occupied after it, and the CPU time it took (s)."""

    camera: str
    time_s: float
    hits: int
    misses: int
    occupied: int
    cpu_s: float


class OccupancyMap:
    """The map of a zone box ``size_m`` (x, y, z) at ``T_world_zone`` (its centre) in
    voxels of ``voxel_m``, with OctoMap's ``hit``/``miss`` probabilities.

    Not thread-safe: one thread integrates; others read :meth:`occupied_centres` copies."""

    def __init__(
        self,
        T_world_zone: np.ndarray,
        size_m: tuple[float, float, float],
        voxel_m: float,
        hit: float = 0.7,
        miss: float = 0.4,
    ) -> None:
        self.T_world_zone = np.asarray(T_world_zone, float)
        self.voxel_m = float(voxel_m)
        self.dims = tuple(max(1, math.ceil(s / voxel_m - 1e-9)) for s in size_m)
        self.size_m = tuple(d * self.voxel_m for d in self.dims)
        self.n = int(np.prod(self.dims))
        self.hit, self.miss = hit, miss
        self.l_hit, self.l_miss = logit(hit), logit(miss)
        self.l_min, self.l_max = logit(miss), logit(OCCUPIED_CLAMP)
        self.log_odds = np.zeros(self.n, np.float32)
        #: voxels the cell file explains (fixtures, parts): never hit
        self.known = np.zeros(self.n, bool)
        self._corner = -np.asarray(self.size_m) / 2  # of the grid, in the zone frame
        self._rays: dict[str, RayTable] = {}
        self._projection: dict[str, tuple[bytes, np.ndarray, np.ndarray, np.ndarray]] = {}
        self._centres: np.ndarray | None = None

    # -- geometry -----------------------------------------------------------------------
    @property
    def half_diagonal_m(self) -> float:
        """From a voxel's centre to its corners (m)."""
        return self.voxel_m * math.sqrt(3) / 2

    def centres(self, index: np.ndarray | None = None) -> np.ndarray:
        """World centres (N x 3) of the voxels ``index`` (flat), or of all."""
        if index is None:
            if self._centres is None:
                self._centres = self._centres_of(np.arange(self.n))
            return self._centres
        return self._centres_of(np.asarray(index))

    def _centres_of(self, index: np.ndarray) -> np.ndarray:
        _, ny, nz = self.dims
        ix, rest = np.divmod(index, ny * nz)
        iy, iz = np.divmod(rest, nz)
        local = (np.stack([ix, iy, iz], axis=1) + 0.5) * self.voxel_m + self._corner
        T = self.T_world_zone
        return np.asarray(local @ T[:3, :3].T + T[:3, 3], np.float64)

    def index_of(self, points_world: np.ndarray) -> np.ndarray:
        """Flat voxel index of each world point (N x 3); -1 outside the zone."""
        T = self.T_world_zone
        local = (np.asarray(points_world, float) - T[:3, 3]) @ T[:3, :3]
        return self._index_local(local)

    def _index_local(self, local: np.ndarray) -> np.ndarray:
        g = np.floor((local - self._corner) / self.voxel_m).astype(np.int64)
        dims = np.asarray(self.dims)
        inside = np.all((g >= 0) & (g < dims), axis=1)
        flat = (g[:, 0] * dims[1] + g[:, 1]) * dims[2] + g[:, 2]
        return np.where(inside, flat, -1)

    def mark_known(
        self, near: Callable[[np.ndarray], np.ndarray], surfaces: np.ndarray, pad_m: float
    ) -> None:
        """Mark the voxels the cell file explains: those whose centres ``near`` says are
        within the padding (plus the half diagonal) of a fixture or part, and those a
        sampled mesh surface point (N x 3, world) lies in, grown by ``pad_m`` (the padding
        plus the half diagonal, m)."""
        self.known |= near(self.centres())
        if len(surfaces):
            from scipy.ndimage import binary_dilation

            index = self.index_of(surfaces)
            mask = np.zeros(self.n, bool)
            mask[index[index >= 0]] = True
            reach = max(1, math.ceil(pad_m / self.voxel_m))
            r = np.arange(-reach, reach + 1)
            ball = (r[:, None, None] ** 2 + r[None, :, None] ** 2 + r[None, None, :] ** 2) <= (
                reach * reach
            )
            grown = binary_dilation(mask.reshape(self.dims), structure=ball)
            self.known |= grown.ravel()

    # -- update -------------------------------------------------------------------------
    def integrate(
        self,
        frame: DepthFrame,
        range_m: tuple[float, float],
        explained: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> MapUpdate:
        """Fold one depth image into the map (module docstring); ``explained(centres)``
        (N x 3 world) says which hit voxels the robot's solids explain."""
        import time

        t0 = time.thread_time()
        rays = self._rays.get(frame.camera)
        if rays is None or not rays.matches(frame):
            rays = self._rays[frame.camera] = RayTable(
                frame.K, frame.size[0], frame.size[1], frame.distortion
            )
        depth = np.where(
            (frame.depth_m >= range_m[0]) & (frame.depth_m <= range_m[1]), frame.depth_m, 0.0
        ).astype(np.float32)
        stride = self._stride(frame)
        points, _ = rays.points(depth, stride)
        T_zone_camera = np.linalg.inv(self.T_world_zone) @ np.asarray(frame.T_world_camera, float)
        local = points @ T_zone_camera[:3, :3].T.astype(np.float32) + T_zone_camera[:3, 3].astype(
            np.float32
        )
        index = self._index_local(local)
        index = index[index >= 0]
        counts = np.bincount(index, minlength=self.n)
        hit_mask = counts >= MIN_POINTS
        hit_mask &= ~self.known
        hits = np.flatnonzero(hit_mask)
        if len(hits) and explained is not None:
            drop = explained(self.centres(hits))
            hit_mask[hits[drop]] = False
            hits = hits[~drop]
        free = self._seen_free(frame, depth)
        free &= ~hit_mask
        lo = self.log_odds
        lo[free] = np.maximum(lo[free] + self.l_miss, self.l_min)
        lo[hits] = np.minimum(lo[hits] + self.l_hit, self.l_max)
        return MapUpdate(
            frame.camera,
            frame.time_s,
            len(hits),
            int(np.count_nonzero(free)),
            int(np.count_nonzero(lo > 0)),
            time.thread_time() - t0,
        )

    def _stride(self, frame: DepthFrame) -> int:
        """Every how many pixels (along each axis) the hits are taken: as many as keep a
        voxel at the zone's far end at least ``MIN_POINTS`` x 3 points of one image (a
        decimation filter before the voxel filter; the misses use every pixel)."""
        T = np.linalg.inv(np.asarray(frame.T_world_camera, float))
        corners = np.array(
            [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
        ) * np.asarray(self.size_m)
        world = corners @ self.T_world_zone[:3, :3].T + self.T_world_zone[:3, 3]
        far_m = float(np.max((world @ T[:3, :3].T + T[:3, 3])[:, 2]))
        footprint_m = far_m / float(min(frame.K[0, 0], frame.K[1, 1]))
        per_axis = self.voxel_m / max(footprint_m, 1e-9)  # pixels across a voxel
        return max(1, int(per_axis / math.sqrt(3 * MIN_POINTS)))

    def _seen_free(self, frame: DepthFrame, depth: np.ndarray) -> np.ndarray:
        """Voxels some ray of this image passed through, entirely in front of the depth its
        pixel measured (bool, every voxel)."""
        pixel, z = self._project(frame)
        measured = np.zeros(self.n, np.float32)
        seen = pixel >= 0
        measured[seen] = depth.ravel()[pixel[seen]]
        return (measured > 0) & (z + self.half_diagonal_m < measured)

    def _project(self, frame: DepthFrame) -> tuple[np.ndarray, np.ndarray]:
        """Every voxel centre's pixel (flat index, -1 outside the image) and depth along the
        camera's Z, cached while the camera stands where it stood (a world mount)."""
        key = (
            np.asarray(frame.T_world_camera, float).tobytes()
            + np.asarray(frame.K, float).tobytes()
            + bytes(str(frame.size), "ascii")
        )
        cached = self._projection.get(frame.camera)
        if cached is not None and cached[0] == key:
            return cached[1], cached[2]
        T = np.linalg.inv(np.asarray(frame.T_world_camera, float))
        p = self.centres() @ T[:3, :3].T + T[:3, 3]
        z = p[:, 2]
        K = np.asarray(frame.K, float)
        width, height = frame.size
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(K[0, 0] * p[:, 0] / z + K[0, 2])
            v = np.rint(K[1, 1] * p[:, 1] / z + K[1, 2])
        inside = (z > 1e-6) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        pixel = np.full(self.n, -1, np.int64)
        pixel[inside] = (v[inside] * width + u[inside]).astype(np.int64)
        z32 = z.astype(np.float32)
        self._projection[frame.camera] = (key, pixel, z32, inside)
        return pixel, z32

    # -- queries ------------------------------------------------------------------------
    def occupied(self) -> np.ndarray:
        """Flat indices of the occupied voxels (p > 0.5)."""
        return np.flatnonzero(self.log_odds > 0)

    def occupied_centres(self) -> np.ndarray:
        """World centres of the occupied voxels (N x 3, m)."""
        return self.centres(self.occupied())

    def clear(self) -> None:
        self.log_odds[:] = 0.0

    # -- snapshots (run/serve save one; check --watch plans against it) ----------------
    def save(self, path: str | Path) -> None:
        """Write the map (zone, voxel, model, log-odds) to an ``.npz`` file."""
        np.savez_compressed(
            Path(path),
            T_world_zone=self.T_world_zone,
            size_m=np.asarray(self.size_m),
            voxel_m=np.asarray(self.voxel_m),
            model=np.asarray([self.hit, self.miss]),
            log_odds=self.log_odds,
        )

    @classmethod
    def load(cls, path: str | Path) -> OccupancyMap:
        """A map written by :meth:`save`; a :class:`~cellrunner.errors.UsageError` naming
        the file when it is not one."""
        try:
            with np.load(Path(path)) as data:
                size = tuple(float(s) for s in data["size_m"])
                hit, miss = (float(v) for v in data["model"])
                m = cls(
                    data["T_world_zone"],
                    (size[0], size[1], size[2]),
                    float(data["voxel_m"]),
                    hit,
                    miss,
                )
                log_odds = np.asarray(data["log_odds"], np.float32)
        except FileNotFoundError:
            raise UsageError(f"{path}: no such file") from None
        except (OSError, KeyError, ValueError, EOFError):
            raise UsageError(
                f"{path}: not a map snapshot (dry-run or serve --save-map writes one)"
            ) from None
        if log_odds.shape != (m.n,):
            raise UsageError(f"{path}: {log_odds.shape[0]} voxels, its zone has {m.n}")
        m.log_odds = log_odds
        return m
