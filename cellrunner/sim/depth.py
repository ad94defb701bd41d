"""Depth images of the twin (SPEC section 12) and the objects only they reveal.

:class:`DepthImager` renders what a depth camera measures with the arm, the parts and the
intruders where they stand: metres along the camera's Z, through the camera's intrinsics
and distortion (the ideal picture MuJoCo renders, resampled as
:class:`~cellrunner.sim.cameras.CameraImager` resamples colour; nearest neighbour, so no
depth is ever blended across an edge), Gaussian noise of ``sim.depth_noise``, and 0 where
the camera measures nothing (the far plane, out of range). Without an OpenGL library it
casts rays instead (MuJoCo's ``mj_multiRay``, on the CPU) at a reduced resolution
(``RAY_STRIDE``): the frame then carries that smaller image's intrinsics.

Intruders (``sim: {intruders}``, ``--inject intrusion@STEP``) are mocap bodies the model
holds from the start, parked far under the floor until they appear: collision geoms like a
fixture's (the arm touching one is a contact, a protective stop), never listed anywhere the
engine reads.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.model.geometry import Shape
from cellrunner.perception.frames import DepthFrame
from cellrunner.sim.cameras import T_CV_MJ, CameraDescription, _ideal_map

#: without GL, one ray is cast per this many pixels along each image axis
RAY_STRIDE = 4
#: where intruders wait, out of every camera's range and the arm's reach (world z, m)
PARK_Z_M = -50.0


@dataclass(frozen=True, eq=False)
class IntruderDescription:
    """An object the cell file does not list: ``shape`` at ``T_world_shape`` from
    ``appear_s`` to ``leave_s`` (None: stays) after the job starts; ``on_inject`` True for
    the box ``--inject intrusion@STEP`` drops, which appears only when injected."""

    name: str
    shape: Shape
    T_world_shape: np.ndarray
    appear_s: float = 0.0
    leave_s: float | None = None
    on_inject: bool = False


def add_intruders(builder: Any, intruders: tuple[IntruderDescription, ...]) -> None:
    """One mocap body per intruder, parked under the floor, with a fixture-like geom."""
    from cellrunner.sim.mjcf_attrs import PADS, PARTS, ROBOT, STATIC

    world = builder.root.find("worldbody")
    for k, intruder in enumerate(intruders):
        body = ET.SubElement(
            world,
            "body",
            name=f"intruder:{intruder.name}",
            mocap="true",
            pos=f"0 0 {PARK_Z_M - 2.0 * k:g}",
        )
        ET.SubElement(
            body,
            "geom",
            name=f"intruder:{intruder.name}",
            material="fixture",
            contype=str(STATIC),
            conaffinity=str(ROBOT | PADS | PARTS),
            **builder._shape_attrs(intruder.shape),
        )


class Intruders:
    """Moves a world's intruders in and out on the job's clock (:meth:`start` at each job's
    start, :meth:`update` every period)."""

    def __init__(self, model: Any, data: Any, intruders: tuple[IntruderDescription, ...]) -> None:
        import mujoco

        self.data, self.intruders = data, intruders
        self.mocap = [
            int(
                model.body_mocapid[
                    mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"intruder:{i.name}")
                ]
            )
            for i in intruders
        ]
        self.parked = [np.array(data.mocap_pos[m]) for m in self.mocap]
        self._geoms = {
            int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"intruder:{i.name}")): i.name
            for i in intruders
        }
        #: intruders something touched (the arm, the tool, a part): the test of "never touched"
        self.touched: set[str] = set()
        self._t0: float | None = None
        self._injected: dict[int, tuple[np.ndarray, float]] = {}  # index -> (pose, since)
        self._shown = [False] * len(intruders)

    def note_contacts(self) -> None:
        """Remember every intruder in contact now (call after each physics step)."""
        if not any(self._shown):
            return
        d = self.data
        for k in range(d.ncon):
            c = d.contact[k]
            for g in (int(c.geom1), int(c.geom2)):
                name = self._geoms.get(g)
                if name is not None and c.dist < 0:
                    self.touched.add(name)

    def start(self, time_s: float) -> None:
        """A job starts now: the scheduled intruders count from here."""
        self._t0 = time_s
        self._injected.clear()

    def inject(self, T_world_shape: np.ndarray, time_s: float) -> str | None:
        """Drop the injectable box at ``T_world_shape`` now; its name, None without one."""
        for k, i in enumerate(self.intruders):
            if i.on_inject:
                self._injected[k] = (np.asarray(T_world_shape, float), time_s)
                return i.name
        return None

    def update(self, time_s: float) -> bool:
        """Put every intruder where it is at ``time_s``; True when any moved (the caller
        runs the kinematics again)."""
        moved = False
        for k, intruder in enumerate(self.intruders):
            pose: np.ndarray | None = None
            if k in self._injected:
                pose = self._injected[k][0]
            elif not intruder.on_inject and self._t0 is not None:
                t = time_s - self._t0
                if t >= intruder.appear_s and (intruder.leave_s is None or t < intruder.leave_s):
                    pose = intruder.T_world_shape
            show = pose is not None
            if show == self._shown[k] and not (show and k in self._injected):
                continue
            m = self.mocap[k]
            if pose is None:
                self.data.mocap_pos[m] = self.parked[k]
                self.data.mocap_quat[m] = (1.0, 0.0, 0.0, 0.0)
            else:
                import mujoco

                quat = np.zeros(4)
                mujoco.mju_mat2Quat(quat, np.ascontiguousarray(pose[:3, :3]).ravel())
                if show != self._shown[k] or not np.allclose(self.data.mocap_pos[m], pose[:3, 3]):
                    self.data.mocap_pos[m] = pose[:3, 3]
                    self.data.mocap_quat[m] = quat
                else:
                    continue
            self._shown[k] = show
            moved = True
        return moved


class DepthImager:
    """Renders one depth camera of a compiled twin model; ``frame(qpos, mocap_pos,
    time_s)`` is what it measures. Holds a GL context when it renders: use it on one
    thread (never the control thread), and ``close()`` it."""

    def __init__(
        self,
        model: Any,
        camera: CameraDescription,
        range_m: tuple[float, float],
        noise_m: float = 0.0,
        seed: int = 0,
        use_gl: bool | None = None,
    ) -> None:
        from cellrunner.sim.mujoco_loader import gl_backend, load_mujoco

        self._mj = load_mujoco()
        self.model, self.camera = model, camera
        self.range_m, self.noise_m = range_m, noise_m
        self.data = self._mj.MjData(model)
        self._rng = np.random.default_rng(seed)
        self.use_gl = gl_backend() is not None if use_gl is None else use_gl
        self._renderer: Any = None
        self._map = _ideal_map(camera) if self.use_gl else None
        self._cam_id = self._mj.mj_name2id(
            model, self._mj.mjtObj.mjOBJ_CAMERA, f"camera:{camera.name}"
        )
        self._rays: tuple[np.ndarray, np.ndarray] | None = None

    def frame(
        self, qpos: np.ndarray, mocap_pos: np.ndarray, mocap_quat: np.ndarray, time_s: float
    ) -> DepthFrame:
        d = self.data
        d.qpos[:] = qpos
        if self.model.nmocap:
            d.mocap_pos[:] = mocap_pos
            d.mocap_quat[:] = mocap_quat
        self._mj.mj_kinematics(self.model, d)
        self._mj.mj_camlight(self.model, d)
        T_world_mj = np.eye(4)
        T_world_mj[:3, :3] = d.cam_xmat[self._cam_id].reshape(3, 3)
        T_world_mj[:3, 3] = d.cam_xpos[self._cam_id]
        T_world_camera = T_world_mj @ T_CV_MJ
        if self.use_gl:
            try:
                depth, K = self._render(), self.camera.K
            except Exception:  # no GL context after all: cast rays from now on
                self.use_gl = False
                self._map = None
        if not self.use_gl:
            depth, K = self._cast(T_world_camera)
        depth = np.asarray(depth, np.float32)
        valid = (depth >= self.range_m[0]) & (depth <= self.range_m[1])
        if self.noise_m > 0:
            depth = depth + self._rng.normal(0.0, self.noise_m, depth.shape).astype(np.float32)
        depth[~valid] = 0.0
        return DepthFrame(
            self.camera.name,
            time_s,
            depth,
            T_world_camera,
            K,
            q_rad=np.array(qpos[:6]),
            distortion=self.camera.distortion if self.use_gl else np.zeros(0),
        )

    def _render(self) -> np.ndarray:
        if self._renderer is None:
            self._renderer = self._mj.Renderer(self.model, self.camera.height, self.camera.width)
            self._renderer.enable_depth_rendering()
        self._renderer.update_scene(self.data, camera=f"camera:{self.camera.name}")
        depth = np.array(self._renderer.render(), np.float32)
        far = self.model.vis.map.zfar * self.model.stat.extent
        depth[depth >= 0.999 * far] = 0.0
        if self._map is None:
            return depth
        import cv2

        return np.asarray(cv2.remap(depth, self._map[0], self._map[1], cv2.INTER_NEAREST))

    def _cast(self, T_world_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Depth by ray casting at 1/RAY_STRIDE of the resolution (an ideal pinhole with the
        camera's focal lengths, scaled); returns the image and its intrinsics."""
        s = RAY_STRIDE
        K = self.camera.K.copy()
        w, h = self.camera.width // s, self.camera.height // s
        K_small = np.array(
            [
                [K[0, 0] / s, 0, (K[0, 2] + 0.5) / s - 0.5],
                [0, K[1, 1] / s, (K[1, 2] + 0.5) / s - 0.5],
                [0, 0, 1],
            ]
        )
        if self._rays is None:
            u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
            x = (u - K_small[0, 2]) / K_small[0, 0]
            y = (v - K_small[1, 2]) / K_small[1, 1]
            rays = np.stack([x.ravel(), y.ravel(), np.ones(w * h)], axis=1)
            norm = np.linalg.norm(rays, axis=1)
            self._rays = (rays / norm[:, None], 1.0 / norm)
        unit, z_per_m = self._rays
        vec = np.ascontiguousarray((unit @ T_world_camera[:3, :3].T).ravel())
        n = len(unit)
        geomid = np.zeros(n, np.int32)
        dist = np.zeros(n, np.float64)
        self._mj.mj_multiRay(
            self.model,
            self.data,
            np.ascontiguousarray(T_world_camera[:3, 3], float),
            vec,
            None,
            1,
            -1,
            geomid,
            dist,
            None,
            n,
            float(self.range_m[1]) * 2,
        )
        z = np.where(geomid >= 0, dist * z_per_m, 0.0)
        return z.reshape(h, w), K_small

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
