"""The live 3D view's data, as the status page's routes serve it (``serve --http``).

:class:`LiveView` turns the samples of a :class:`~cellrunner.web.live_feed.LiveFeed` into
JSON for the page, on the web threads: the scene once (``/live/scene.json``), each
sample's state (``/live/state.json``, and the ``/live/stream`` of server-sent events),
each job's planned path (``/live/job.json``). Every answer is built once and cached (the
scene for good, the state per sample, the path per job), so five open pages cost what one
does; the control loop only ever published a reference.

The state of one sample::

    {"seq": 12, "time_s": 3.21, "q_deg": [...6], "links": [[16] x 7], "flange": [16],
     "tcp": [x, y, z], "tool": "", "job_id": "...", "step": 4,
     "carried": {"name", "T"} | null,
     "map": {"voxel": m, "centres": [x, y, z, ...]} | null, "obstructed": false,
     "obstruction": "", "blocked": [x, y, z] | null}

``links`` are the ``T_world_link`` of the base and the six moving links (row-major 4x4),
``tool`` the tool mounted (:func:`~cellrunner.web.live_scene.tool_key`; "" the cell
file's, the others' shapes are in the job's JSON), ``carried`` the part in the gripper
(``T_world_part``; its shape is in the job's JSON),
``map`` the occupied voxels of the watched zone, ``blocked`` the voxel that stops the arm.
"""

from __future__ import annotations

import json
import threading
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.web.live_feed import LiveFeed, LiveSample
from cellrunner.web.live_scene import (
    DECIMALS,
    ArmPoses,
    carried_part,
    job_of,
    matrix_json,
    scene_of,
    tool_key,
    world_at,
)

if TYPE_CHECKING:
    from cellrunner.execution.watch import ZoneWatch
    from cellrunner.planning.world import CellWorld

#: the most map voxels one state carries (the rest are left out, the count says how many)
MAP_VOXELS_MAX = 5000


def _json(value: Any) -> bytes:
    return json.dumps(value, separators=(",", ":"), allow_nan=False).encode()


class LiveView:
    """See the module docstring. Build it before serving (it loads the arm's geometry and
    the cell's meshes), then any web thread may call it."""

    def __init__(self, feed: LiveFeed, world: CellWorld, zone: ZoneWatch | None = None) -> None:
        self.feed, self.world, self.zone = feed, world, zone
        self.scene = _json(scene_of(world, zone.watch if zone is not None else None))
        self._poses = ArmPoses(world.kinematics)
        self._lock = threading.Lock()  # the caches and the pose data: one web thread at a time
        self._state: tuple[int, bytes] | None = None
        self._job: tuple[str, bytes] | None = None
        self._job_pending = b'{"job_id":"","path":[],"parts":{}}'

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.feed.period_s

    def state(self) -> tuple[int, bytes]:
        """The latest sample's state (its ``seq``, the JSON); seq 0 before the first."""
        sample = self.feed.latest
        if sample is None:
            return 0, b'{"seq":0}'
        with self._lock:
            if self._state is None or self._state[0] != sample.seq:
                self._state = (sample.seq, _json(self._state_of(sample)))
            return self._state

    def job(self) -> bytes:
        """The running job's planned path and carried parts (an empty path while it
        plans, or with no job)."""
        sample = self.feed.latest
        if sample is None or sample.plan is None:
            return self._job_pending
        with self._lock:
            if self._job is None or self._job[0] != sample.job_id:
                job = job_of(sample.job_id, sample.plan, self.world)
                self._job = (sample.job_id, _json(job))
            return self._job[1]

    def _state_of(self, sample: LiveSample) -> dict[str, Any]:
        q = np.array(sample.q_rad)
        poses = self._poses.links(q)
        mounted = world_at(sample.plan, sample.step_index) or self.world
        T_world_tcp = poses[7] @ mounted.kinematics.T_flange_tcp  # the tool mounted now
        part = carried_part(sample.plan, sample.step_index)
        carried = None
        if part is not None:
            carried = {"name": part.name, "T": matrix_json(T_world_tcp @ part.T_parent_shape)}
        return {
            "seq": sample.seq,
            "time_s": round(sample.time_s, 4),
            "q_deg": [round(float(v), 4) for v in np.degrees(q)],
            "links": [matrix_json(T) for T in poses[:7]],
            "flange": matrix_json(poses[7]),
            "tcp": [round(float(v), DECIMALS) for v in T_world_tcp[:3, 3]],
            "tool": tool_key(mounted),
            "job_id": sample.job_id,
            "step": sample.step_index,
            "carried": carried,
            "obstructed": sample.obstructed,
            "obstruction": sample.obstruction,
            **self._map(sample.obstructed),
        }

    def _map(self, obstructed: bool) -> dict[str, Any]:
        zone = self.zone
        if zone is None:
            return {"map": None, "blocked": None}
        centres = zone.map.occupied_centres()  # a copy; a torn read shows a voxel late
        verdict = zone.verdict() if obstructed else None
        blocked = verdict.blocked if verdict is not None else None
        return {
            "map": {
                "voxel": zone.map.voxel_m,
                "occupied": len(centres),
                "centres": [
                    round(float(v), DECIMALS) for v in centres[:MAP_VOXELS_MAX].reshape(-1)
                ],
            },
            "blocked": list(blocked.voxel_m) if blocked is not None else None,
        }
