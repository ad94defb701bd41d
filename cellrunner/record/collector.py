"""The recorder: a control-loop observer that takes a small snapshot at ``SAMPLE_HZ`` of the
backend's clock (the measured joints, the twin's state when there is one, wrench, IO, the
step under way, the trajectory streamed) and puts it in a queue; a worker thread poses the
scene and writes it through a :class:`~cellrunner.record.sink.Sink`. The loop's thread
never waits for it: a full queue drops the sample (counted in ``dropped``).

One recording per job (``serve``, a sink opened per job id) or one for the whole run
(``dry-run``, ``run``); ``open_sink(job_id)`` opens the file a job goes to."""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.record.sink import Rgba, Sink

if TYPE_CHECKING:
    from cellrunner.execution.cell import CellController
    from cellrunner.record.scene import SceneModel

#: snapshots per second of backend time (the controller runs at 125-500 Hz)
SAMPLE_HZ = 50.0

#: snapshots waiting for the worker before new ones are dropped
QUEUE_SIZE = 4096

#: the measured path is written again at most this often (s of backend time)
PATH_EVERY_S = 0.5

#: planned path points kept per trajectory
PLAN_POINTS = 120

PLANNED: Rgba = (0.2, 0.5, 1.0, 1.0)
MEASURED: Rgba = (1.0, 0.55, 0.1, 1.0)
OBSTACLES: Rgba = (0.9, 0.1, 0.1, 1.0)


@dataclass(frozen=True)
class Snapshot:
    """What the loop's thread copies at one sample (nothing is computed there)."""

    time_s: float
    q_rad: np.ndarray
    qpos: np.ndarray | None  # the twin's whole state (parts, jaws), None on a real arm
    wrench_N: np.ndarray
    io: dict[str, float]  # IO name -> value
    job_id: str
    step: int  # 1-based step under way, 0 none
    plan: Any  # the ApprovedTrajectory streamed now, or None
    ended: Any  # the JobView of a job that ended since the last snapshot, or None
    started: str = ""  # "4 grip infeed": the step that started since the last snapshot


class Collector:
    """Control-loop observer (module docstring). ``scene_of()`` builds the scene on the
    worker; ``qpos_of()`` copies the twin's state (None: a real arm);
    ``open_sink(job_id)`` the file a job is written to (``per_job``: a file per job, else
    one for the whole run); ``io_names``: IO name -> channel;
    ``obstacles_of()`` the obstacle map's occupied points (N x 3, world), if watched;
    ``depth_of()`` each depth camera's latest frame (a DepthFrame: image, pose, time);
    ``pictures_of()`` each camera's latest picture an align step looked at;
    ``warm_up()`` runs first on the worker (the writer's imports)."""

    def __init__(
        self,
        scene_of: Callable[[], SceneModel],
        open_sink: Callable[[str], Sink],
        io_names: Mapping[str, str],
        *,
        qpos_of: Callable[[], np.ndarray | None] | None = None,
        obstacles_of: Callable[[], np.ndarray | None] | None = None,
        depth_of: Callable[[], dict[str, Any]] | None = None,
        pictures_of: Callable[[], dict[str, np.ndarray]] | None = None,
        per_job: bool = False,
        warm_up: Callable[[], None] | None = None,
    ) -> None:
        self.per_job, self._warm_up = per_job, warm_up
        self._scene_of, self._open_sink = scene_of, open_sink
        self.io_names = dict(io_names)
        self._qpos_of, self._obstacles_of, self._depth_of = qpos_of, obstacles_of, depth_of
        self._pictures_of = pictures_of
        self._queue: queue.Queue[Snapshot | None] = queue.Queue(QUEUE_SIZE)
        self._next_s = -1.0
        self._last_view: Any = None
        self._step = 0
        self.dropped = 0
        self.written = 0
        self.error: str | None = None  # what stopped the worker, if anything
        self._worker = threading.Thread(target=self._work, name="recorder", daemon=True)
        self._worker.start()

    # -- the control loop's thread: copy and queue, nothing else ------------------------
    def quiet_until_s(self, cell: CellController) -> float:
        """The next sample's time (s): the loop may look ahead until then."""
        return self._next_s

    def __call__(self, cell: CellController) -> None:
        state = cell.backend.read_state()
        ended = cell.last_job
        if state.time_s < self._next_s and ended is self._last_view:
            return
        self._next_s = state.time_s + 1.0 / SAMPLE_HZ
        view = cell.job_view(records=False)
        started = ""
        if view is not None and view.step and view.step != self._step:
            full = cell.job_view()  # the step rows copied: once per step, not per sample
            rows = {r.index: r for r in full.records} if full is not None else {}
            row = rows.get(view.step)
            started = f"{view.step} {row.kind} {row.name}" if row is not None else str(view.step)
        self._step = view.step if view is not None else 0
        streaming = cell.streaming()
        values = {**state.outputs, **state.inputs}
        snap = Snapshot(
            time_s=state.time_s,
            q_rad=state.q_rad.copy(),
            qpos=self._qpos_of() if self._qpos_of is not None else None,
            wrench_N=np.array(state.wrench_N, float),
            io={
                name: float(values.get(channel, values.get(name, 0.0)) or 0.0)
                for name, channel in self.io_names.items()
            },
            job_id=view.job_id if view is not None else "",
            step=view.step if view is not None else 0,
            plan=streaming[0] if streaming is not None else None,
            ended=ended if ended is not self._last_view else None,
            started=started,
        )
        self._last_view = ended
        try:
            self._queue.put_nowait(snap)
        except queue.Full:
            self.dropped += 1

    # -- any thread ---------------------------------------------------------------------
    def close(self, timeout_s: float = 30.0) -> None:
        """Write what is queued, close the files, stop the worker."""
        with contextlib.suppress(queue.Full):
            self._queue.put(None, timeout=timeout_s)
        self._worker.join(timeout_s)

    # -- the worker -----------------------------------------------------------------------
    def _work(self) -> None:
        writer: _Writer | None = None
        try:
            if self._warm_up is not None:
                self._warm_up()  # the writer's imports, before any job
            scene: SceneModel | None = None
            while (snap := self._queue.get()) is not None:
                if scene is None:  # the first snapshot: the twin is built by now
                    scene = self._scene_of()
                writer = self._writer_for(snap, writer, scene)
                if writer is None:
                    continue  # serve between jobs: nothing recorded
                writer.write(snap, self)
                self.written += 1
                if self.per_job and snap.ended is not None and not snap.job_id:
                    writer.close()  # the job's end is in its file
                    writer = None
        except Exception as exc:  # a recording must never take the cell down
            self.error = f"{type(exc).__name__}: {exc}"
            while self._queue.get() is not None:  # keep draining until closed
                pass
        finally:
            if writer is not None:
                with contextlib.suppress(Exception):
                    writer.close()

    def _writer_for(
        self, snap: Snapshot, writer: _Writer | None, scene: SceneModel
    ) -> _Writer | None:
        """The open recording ``snap`` goes to: one for the whole run, or (``per_job``)
        the file of the job under way, opened as it starts, none between jobs."""
        if not self.per_job:
            if writer is None:
                return _Writer(scene, self._open_sink(snap.job_id), snap.job_id)
            writer.job_id = snap.job_id or writer.job_id
            return writer
        if not snap.job_id:
            return writer if snap.ended is not None else None
        if writer is not None and writer.job_id == snap.job_id:
            return writer
        if writer is not None:
            writer.close()
        return _Writer(scene, self._open_sink(snap.job_id), snap.job_id)


class _Writer:
    """One open recording: the meshes once, then each snapshot."""

    def __init__(self, scene: SceneModel, sink: Sink, job_id: str) -> None:
        self.scene, self.sink, self.job_id = scene, sink, job_id
        self.poses: dict[str, np.ndarray] = {}
        self.measured: list[np.ndarray] = []
        self.path_at_s = -1.0
        self.plan: Any = None
        self.step = -1
        self.obstacles_at_s = -1.0
        self.frames: dict[str, Any] = {}  # the depth image of each camera written last
        self.pictures: dict[str, np.ndarray] = {}  # the picture of each camera written last
        for mesh in scene.meshes:
            sink.mesh(mesh.path, mesh.vertices_m, mesh.faces, mesh.rgba)

    def write(self, snap: Snapshot, collector: Collector) -> None:
        sink, t = self.sink, snap.time_s
        qpos = snap.qpos if snap.qpos is not None else snap.q_rad
        poses, T_tcp = self.scene.posed(qpos)
        for path, T in poses.items():
            last = self.poses.get(path)
            if last is None or not np.allclose(last, T, atol=1e-6):
                sink.pose(t, path, T)
                self.poses[path] = T
                time.sleep(0)  # the GIL to a waiting thread (the control loop) between bodies
        sink.pose(t, "world/tcp", T_tcp)
        self.measured.append(T_tcp[:3, 3].copy())
        if t - self.path_at_s >= PATH_EVERY_S and len(self.measured) > 1:
            sink.line(t, "world/paths/measured", np.array(self.measured), MEASURED)
            self.path_at_s = t
        if snap.plan is not None and snap.plan is not self.plan:
            self.plan = snap.plan
            q = snap.plan.trajectory.q_rad
            rows = q[np.linspace(0, len(q) - 1, min(len(q), PLAN_POINTS)).astype(int)]
            sink.line(t, "world/paths/planned", self.scene.tcp_path_m(qpos, rows), PLANNED)
        for i, q in enumerate(snap.q_rad):
            sink.scalar(t, f"plots/joints/q{i + 1}_rad", float(q))
        sink.scalar(t, "plots/wrist/force_N", float(np.linalg.norm(snap.wrench_N[:3])))
        for name, value in snap.io.items():
            sink.scalar(t, f"plots/io/{name}", value)
        if snap.step != self.step:
            self.step = snap.step
            sink.scalar(t, "plots/step", float(snap.step))
        if snap.started:
            sink.text(t, "steps", f"step {snap.started}: started", "INFO")
        if snap.ended is not None:
            self._ended(t, snap.ended)
        self._perception(t, collector)

    def _ended(self, t: float, view: Any) -> None:
        """The job's step timeline with each step's result, and its result."""
        for r in sorted(view.records, key=lambda r: r.started_s or 0.0):
            if r.started_s is None:
                continue
            level = "INFO" if r.status.value in ("ok", "skipped") else "ERROR"
            line = f"step {r.index} {r.kind} {r.name}: {r.status.value} ({r.duration_s:.2f} s)"
            at_s = min(t, r.started_s + r.duration_s)  # as it ended (MCAP: logged now)
            self.sink.text(at_s, "steps", f"{line} {r.message}".rstrip(), level)
        code = view.result_code
        level = "INFO" if code is None or int(code) == 0 else "ERROR"
        name = code.name if code is not None else "?"
        message = f" {view.message}" if view.message and view.message != name else ""
        self.sink.text(t, "steps", f"job {view.job_id}: {name}{message}", level)
        if len(self.measured) > 1:
            self.sink.line(t, "world/paths/measured", np.array(self.measured), MEASURED)

    def _perception(self, t: float, collector: Collector) -> None:
        if collector._pictures_of is not None:  # an align step's look: each one written
            for name, picture in collector._pictures_of().items():
                if self.pictures.get(name) is not picture:
                    self.pictures[name] = picture
                    self.sink.image(t, f"cameras/{name}/image", picture)
        if t - self.obstacles_at_s < PATH_EVERY_S:
            return
        self.obstacles_at_s = t
        if collector._obstacles_of is not None:
            points = collector._obstacles_of()
            if points is not None:
                self.sink.points(t, "world/obstacles", points, OBSTACLES)
        if collector._depth_of is not None:
            for name, frame in collector._depth_of().items():
                if self.frames.get(name) is not frame:  # a new image since the last look
                    self.frames[name] = frame
                    at_s = min(t, frame.time_s)
                    self.sink.pose(at_s, f"world/cameras/{name}", frame.T_world_camera)
                    self.sink.depth(at_s, f"cameras/{name}/depth", frame.depth_m)

    def close(self) -> None:
        self.sink.close()
