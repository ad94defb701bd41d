"""The watched zone while jobs run (SPEC section 12): the live map, what it says about the
motion under way, and the feed that brings it depth images.

Threads. :class:`ZoneWatch` is shared: a depth feed integrates images into its map on its
own thread (never the control thread) and, after each, checks the rest of the motion under
way against the map; the control thread reads the latest verdict (:meth:`ZoneWatch.verdict`,
no waiting) and tells it what it streams (:meth:`ZoneWatch.follow`). One lock guards the
map and the verdict; the control thread holds it only to copy a few references.

:class:`TwinDepthFeed` is the feed of a rehearsal on the in-process twin: a control-loop
observer that, at each depth camera's rate in simulated time, has the backend copy its scene
(:class:`~cellrunner.backends.base.RendersDepth`: the twin renders its own images) and the
image rendered and integrated on a worker thread. Off real time
(dry-run) the loop waits for that worker, and the verdict becomes visible as long after
the image was taken (simulated) as the work took the worker's thread in CPU time (wall
time on a machine shared with other processes would charge their time); in real time
verdicts are published as they come.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.backends.base import DepthRenderer, RendersDepth
from cellrunner.model.geometry import Placed
from cellrunner.perception.frames import DepthFrame
from cellrunner.perception.known import KnownScene
from cellrunner.perception.occupancy import MapUpdate, OccupancyMap
from cellrunner.perception.path_check import Blocked, first_blocked
from cellrunner.perception.solids import near_any

if TYPE_CHECKING:
    from cellrunner.model.watch import Watch
    from cellrunner.planning.world import CellWorld


@dataclass(frozen=True)
class Verdict:
    """What the map said, after the image taken at ``time_s``, of the motion followed
    then: ``blocked`` (None: clear) with the set-point index in ``follow_id``'s
    trajectory; ``occupied`` voxels in the map."""

    time_s: float
    follow_id: int
    blocked: Blocked | None
    occupied: int


#: beyond the cubes an arm stands in, the planner's clearance (m): also left out for a start
STAND_CLEAR_M = 0.005


class ZoneWatch:
    """The map of one watched cell and the verdicts on the motion under way."""

    def __init__(self, world: CellWorld, watch: Watch) -> None:
        self.world, self.watch = world, watch
        self.map = OccupancyMap(
            watch.zone.pose.matrix(),
            (watch.zone.box.size[0], watch.zone.box.size[1], watch.zone.box.size[2]),
            watch.voxel,
            watch.occupancy.hit,
            watch.occupancy.miss,
        )
        self.known = KnownScene(world)
        #: a voxel centre this close to the robot's solids: the voxel is within the padding
        self.pad_m = watch.padding + self.map.half_diagonal_m
        static = self.known.static_solids()
        self.map.mark_known(
            lambda c: near_any(static, c, self.pad_m),
            self.known.static_surfaces(watch.voxel / 2),
            self.pad_m,
        )
        self.ranges: dict[str, tuple[float, float]] = {}
        for name in watch.cameras:
            depth = world.loaded.cell.cameras[name].depth
            assert depth is not None  # the loader checked every watched camera has depth
            self.ranges[name] = depth.range_m
        self._lock = threading.Lock()
        self._follow: tuple[int, np.ndarray, int, Placed | None] | None = None  # id, q, from, held
        self._follow_id = 0
        self._verdict: Verdict | None = None
        self.updates: list[MapUpdate] = []  # the last ones (at most 1000)
        self.last_frames: dict[str, DepthFrame] = {}  # each camera's latest (a recording's)
        self.images = 0  # integrated so far
        #: every voxel occupied at any time (for the report's map)
        self.ever_occupied = np.zeros(self.map.n, bool)
        #: the part the arm carries (TCP frame), as the last motion followed said
        self.held: Placed | None = None
        #: replans around the map run on a worker thread while the control loop ticks on
        #: (real time); off real time the loop waits for them (simulated time stands)
        self.replan_in_background = False

    # -- control thread ---------------------------------------------------------------
    def follow(
        self, q_rad: np.ndarray | None, from_index: int = 0, held: Placed | None = None
    ) -> int:
        """The motion under way from now (set-points ``q_rad``, the next one ``from_index``),
        checked after every image; None: the arm stands. Returns its id for :meth:`verdict`."""
        with self._lock:
            self._follow_id += 1
            self._follow = None if q_rad is None else (self._follow_id, q_rad, from_index, held)
            if q_rad is not None:
                self.held = held
            return self._follow_id

    def advance(self, from_index: int) -> None:
        """The motion followed has reached set-point ``from_index``."""
        with self._lock:
            f = self._follow
            if f is not None:
                self._follow = (f[0], f[1], from_index, f[3])

    def set_down(self, part: Placed, q_rad: np.ndarray) -> None:
        """The arm released ``part`` (placed in the TCP frame) with its joints at ``q_rad``:
        the part stands there now, known (its voxels are cleared and never hit again)."""
        from cellrunner.perception.solids import solid_of

        T_world_tcp = self.world.kinematics.T_world_tcp(np.asarray(q_rad, float))
        self.known.set_down(part, T_world_tcp)
        placed = [(solid_of(part.shape), T_world_tcp @ part.T_parent_shape)]
        with self._lock:
            near = near_any(placed, self.map.centres(), self.pad_m)
            self.map.known |= near
            self.map.log_odds[near] = np.minimum(self.map.log_odds[near], 0.0)

    def verdict(self) -> Verdict | None:
        return self._verdict

    def check(self, q_rad: np.ndarray, held: Placed | None = None) -> Blocked | None:
        """Now, on the calling thread: where ``q_rad`` (N x 6) meets the map (None: clear)."""
        with self._lock:
            centres = self.map.occupied_centres()
        return first_blocked(self.known, q_rad, centres, self.pad_m, held=held)

    def obstacles(
        self, scale: float = 1.0, leaving: np.ndarray | None = None, held: Placed | None = None
    ) -> Placed | None:
        """The occupied voxels grown by the padding (as the path check reads it), as one
        obstacle to plan around (a coal octree); None when the map is empty. ``scale``
        grows them further: the path check grows each robot solid along its own faces, so
        near a solid's edge turned away from the world axes it reaches up to sqrt(3) x as
        far as a world-aligned cube does. ``leaving``: where the arm stands (with
        ``held``); the cubes it stands in are left out, so that a plan can start there
        (the arm stopped short of the map as the path check reads it, inside the larger
        cubes): the path check then judges the whole plan against every voxel."""
        from cellrunner.model.geometry import Voxels

        with self._lock:
            centres = self.map.occupied_centres()
        if not len(centres):
            return None
        # grown so that every point the path check calls too near lies inside (the
        # padding, the half diagonal, half its step; a cube covers half a voxel itself)
        from cellrunner.perception.path_check import STEP_M

        grow_m = scale * (self.pad_m + STEP_M / 2) - self.map.voxel_m / 2
        if leaving is not None:
            robot = self.known.robot_at(leaving, held)
            reach_m = math.sqrt(3.0) * (grow_m + self.map.voxel_m / 2) + STAND_CLEAR_M
            centres = centres[~near_any(robot, centres, reach_m)]
            if not len(centres):
                return None
        return Placed("watched zone", Voxels(centres, self.map.voxel_m, grow_m), np.eye(4))

    # -- feed thread --------------------------------------------------------------------
    def integrate(self, frame: DepthFrame, held: Placed | None = None) -> Verdict:
        """Fold one image in (the robot's solids at the frame's joints explain theirs) and
        check the motion followed against the map."""
        q = frame.q_rad
        held = held if held is not None else self.held
        robot = self.known.robot_at(q, held) if q is not None else []
        explain = (lambda c: near_any(robot, c, self.pad_m)) if robot else None
        with self._lock:
            update = self.map.integrate(frame, self.ranges[frame.camera], explain)
            occupied = self.map.occupied()
            self.ever_occupied[occupied] = True
            centres = self.map.centres(occupied)
            follow = self._follow
        self.updates.append(update)
        self.last_frames[frame.camera] = frame
        self.images += 1
        if len(self.updates) > 1000:
            del self.updates[:500]
        blocked = None
        follow_id = 0
        if follow is not None:
            follow_id, q_all, start, carried = follow
            rest = first_blocked(self.known, q_all[start:], centres, self.pad_m, held=carried)
            if rest is not None:
                blocked = Blocked(rest.index + start, rest.voxel_m, rest.voxels)
        verdict = Verdict(frame.time_s, follow_id, blocked, update.occupied)
        return verdict

    def publish(self, verdict: Verdict) -> None:
        self._verdict = verdict

    def clearance_m(self, q_rad: np.ndarray) -> tuple[float, str]:
        """For the jog governor: how far (m, 0 when within the padding) the robot at
        ``q_rad`` stays from the nearest occupied voxel beyond the padding, and where."""
        with self._lock:
            centres = self.map.occupied_centres()
        if not len(centres):
            return float("inf"), ""
        blocked = first_blocked(self.known, np.asarray(q_rad, float)[None], centres, self.pad_m)
        if blocked is not None:
            x, y, z = blocked.voxel_m
            return 0.0, f"occupied voxel at ({x:.2f}, {y:.2f}, {z:.2f}) m"
        tcp = self.world.kinematics.p_world_tcp(np.asarray(q_rad, float))
        d = np.linalg.norm(centres - tcp, axis=1)
        k = int(np.argmin(d))
        x, y, z = centres[k]
        return float(d[k]) - self.pad_m, f"occupied voxel at ({x:.2f}, {y:.2f}, {z:.2f}) m"


class TwinDepthFeed:
    """Control-loop observer: the twin's depth cameras at their rates (module docstring)."""

    def __init__(
        self, zone: ZoneWatch, backend: RendersDepth, *, realtime: bool = False, seed: int = 0
    ) -> None:
        self.zone, self.backend, self.realtime, self.seed = zone, backend, realtime, seed
        rates = backend.depth_rates_hz()
        self.rates = {name: rate for name, rate in rates.items() if name in zone.ranges}
        self.next_s = dict.fromkeys(self.rates, 0.0)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="depth")
        self._imagers: dict[str, DepthRenderer] = {}
        self._pending: list[tuple[float, Verdict]] = []  # (visible from s, verdict)
        self._running: Future[tuple[Verdict, float]] | None = None
        self._running_at = 0.0
        self.render_s: list[float] = []

    def start(self) -> None:
        """Nothing to connect: the twin is in this process."""

    def quiet_until_s(self, cell: Any) -> float:
        """The next image, or a verdict's publication; none while the last verdict
        blocks the path (the job reacts to it in the coming periods, one at a time)."""
        verdict = self.zone.verdict()
        if verdict is not None and verdict.blocked is not None:
            return 0.0
        times = [*self.next_s.values(), *(t for t, _ in self._pending)]
        return min(times, default=float("inf"))

    def __call__(self, cell: Any) -> None:
        now = self.backend.depth_time_s()
        if now is None:
            return
        if self._running is not None and (not self.realtime or self._running.done()):
            verdict, wall_s = self._running.result()
            self._pending.append((self._running_at + wall_s, verdict))
            self._running = None
        for item in list(self._pending):
            if now >= item[0] - 1e-9:
                self._pending.remove(item)
                self.zone.publish(item[1])
        if self._running is not None:
            return
        for name, due in self.next_s.items():
            if now >= due - 1e-9:
                self.next_s[name] = max(due + 1.0 / self.rates[name], now)
                snapshot = self.backend.depth_scene()
                self._running_at = now
                self._running = self._pool.submit(self._work, name, snapshot, now, None)
                if not self.realtime:  # off real time: simulated time waits for the image
                    verdict, took_s = self._running.result()
                    self._pending.append((now + took_s, verdict))
                    self._running = None
                return

    def _work(
        self, name: str, snapshot: object, time_s: float, held: Placed | None
    ) -> tuple[Verdict, float]:
        """Render, integrate and check one image; returns the verdict and how long the
        cell's part took: off real time this thread's CPU time for integrating and checking
        (the render stands in for the camera's exposure, and wall time on a shared machine
        would charge other processes' time); in real time the wall time of it all."""
        clock = time.perf_counter if self.realtime else time.thread_time
        w0 = time.perf_counter()
        t0 = clock()
        imager = self._imagers.get(name)
        if imager is None:
            near, far = self.zone.ranges[name]
            imager = self._imagers[name] = self.backend.depth_renderer(name, (near, far), self.seed)
        frame = imager.frame(snapshot, time_s)
        self.render_s.append(time.perf_counter() - w0)
        if not self.realtime:
            t0 = clock()
        verdict = self.zone.integrate(frame, held)
        return verdict, clock() - t0

    def close(self) -> None:
        self._pool.submit(self._close_imagers).result(timeout=10)
        self._pool.shutdown(wait=True)

    def _close_imagers(self) -> None:
        for imager in self._imagers.values():
            imager.close()
        self._imagers.clear()


def watch_on_twin(
    world: CellWorld, backend: RendersDepth, *, realtime: bool
) -> tuple[ZoneWatch, TwinDepthFeed] | None:
    """The watched zone of a cell run on the in-process twin, and its depth feed (add it
    to the control loop's observers); None when the cell is not watched."""
    watch = world.loaded.cell.watch
    if watch is None:
        return None
    zone = ZoneWatch(world, watch)
    return zone, TwinDepthFeed(zone, backend, realtime=realtime)


class SourceDepthFeed:
    """Depth cameras on the arm (:mod:`cellrunner.perception.sources`) feeding the zone:
    one thread per camera grabs, integrates and checks, and publishes each verdict as it
    comes. As a control-loop observer it keeps the arm's latest measured state, whose
    clock and joints stamp each image (a camera's own latency is not modelled). ``start``
    connects the cameras; ``close`` stops the threads and closes them."""

    #: a camera that failed is tried again after this long (s)
    RETRY_S = 1.0

    def __init__(self, zone: ZoneWatch, sources: dict[str, Any], log: Any = None) -> None:
        self.zone, self.sources, self.log = zone, sources, log
        self._stamp: tuple[float, np.ndarray] | None = None  # the arm's clock (s), joints
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        cell = zone.world.loaded.cell
        from cellrunner.model.camera import FLANGE
        from cellrunner.model.expand import frame_pose

        self._mounts: dict[str, tuple[bool, np.ndarray]] = {}
        for name in sources:
            camera = cell.cameras[name]
            if camera.mount == FLANGE:
                self._mounts[name] = (True, camera.pose.matrix())
            else:
                self._mounts[name] = (False, frame_pose(cell, camera.mount) @ camera.pose.matrix())
        self.errors: list[str] = []

    def start(self) -> None:
        for source in self.sources.values():
            source.connect()
        for name, source in self.sources.items():
            thread = threading.Thread(
                target=self._run, args=(name, source), name=f"depth-{name}", daemon=True
            )
            thread.start()
            self._threads.append(thread)

    def __call__(self, cell: Any) -> None:
        state = cell.backend.read_state()
        self.measured(state.time_s, state.q_rad)

    def measured(self, time_s: float, q_rad: np.ndarray) -> None:
        """The arm's latest clock and joints, which stamp the next images (the jog
        session, which has no control loop, calls this each period)."""
        self._stamp = (time_s, q_rad)

    def quiet_until_s(self, cell: Any) -> float:
        return 0.0  # verdicts come on their own clock: no look-ahead

    def _run(self, name: str, source: Any) -> None:
        on_flange, T_mount_camera = self._mounts[name]
        while not self._stop.is_set():
            try:
                image = source.grab()
                stamp = self._stamp
                if stamp is None:
                    continue
                time_s, q_rad = stamp
                T = (
                    self.zone.world.kinematics.T_world_flange(q_rad) @ T_mount_camera
                    if on_flange
                    else T_mount_camera
                )
                frame = DepthFrame(name, time_s, image.depth_m, T, image.K, q_rad=q_rad)
                self.zone.publish(self.zone.integrate(frame))
            except Exception as exc:  # a camera that fails is reported and tried again
                self.errors.append(f"{name}: {exc}")
                if self.log is not None:
                    self.log.warning("depth_camera_failed", camera=name, error=str(exc))
                self._stop.wait(self.RETRY_S)

    def close(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=5.0)
        for source in self.sources.values():
            source.close()


def watch_on_sources(
    world: CellWorld, spec: str | None, host: str | None, log: Any = None
) -> tuple[ZoneWatch, SourceDepthFeed] | None:
    """The watched zone of a cell run on the arm (or the twin's virtual controller), fed
    by the depth source ``spec`` names (:func:`~cellrunner.perception.sources.depth_source`);
    None when the cell is not watched. ``start()`` the feed after the robot is connected."""
    from cellrunner.perception.sources import depth_source

    watch = world.loaded.cell.watch
    if watch is None:
        return None
    cameras = world.loaded.cell.cameras
    sources = {name: depth_source(spec, name, cameras[name], host) for name in watch.cameras}
    zone = ZoneWatch(world, watch)
    return zone, SourceDepthFeed(zone, sources, log)


def watch_cell(
    world: CellWorld,
    backend: Any,
    *,
    realtime: bool,
    depth_source: str | None = None,
    host: str | None = None,
    log: Any = None,
) -> tuple[ZoneWatch, TwinDepthFeed | SourceDepthFeed] | None:
    """The watched zone of a cell and its depth feed: a backend that renders its depth
    cameras itself (:class:`~cellrunner.backends.base.RendersDepth`, the in-process twin)
    feeds its own; on the arm, or the twin's virtual controller, images come from
    ``depth_source`` (default: the twin's on ``host``). None when the cell is not
    watched. Add the feed to the control loop's observers and ``start()`` it once the
    robot is connected; ``close()`` it at the end."""
    from cellrunner.backends.base import RendersDepth

    watched: tuple[ZoneWatch, TwinDepthFeed | SourceDepthFeed] | None
    if isinstance(backend, RendersDepth):
        watched = watch_on_twin(world, backend, realtime=realtime)
    else:
        watched = watch_on_sources(world, depth_source, host, log)
        realtime = True  # the arm's clock
    if watched is not None:
        watched[0].replan_in_background = realtime
    return watched
