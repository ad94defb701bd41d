"""The cell's bodies as the twin models them: one triangle mesh per visible geom (the
arm's meshes, the tool, fixtures, parts, with their colours) in its body's frame, and the
bodies' world poses from a MuJoCo state (``qpos``), computed on the recorder's worker.

The model is the twin's (``SimWorld.model``: the part in the gripper moves with it); on a
real arm, the same model compiled from the cell, posed by the measured joints."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.record.sink import Rgba

#: MuJoCo's geom types (mjtGeom)
_PLANE, _HFIELD, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = range(8)

#: facets around a round primitive
_SEGMENTS = 20

#: geom groups drawn (MuJoCo's viewer shows 0-2 by default)
_VISIBLE_GROUPS = 3


@dataclass(frozen=True)
class GeomMesh:
    """One geom as triangles in its body's frame (m)."""

    path: str  # entity path, world/<body>/<geom>
    vertices_m: np.ndarray
    faces: np.ndarray
    rgba: Rgba


def entity_name(name: str, fallback: str) -> str:
    """``name`` as one entity path segment (letters, digits, ``_`` and ``-``)."""
    cleaned = re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_")
    return cleaned or fallback


class SceneModel:
    """The meshes of a MuJoCo model and its bodies' world poses for a ``qpos``."""

    def __init__(self, model: Any, tcp_site: str = "tcp") -> None:
        import mujoco

        self._mj = mujoco
        self.model = model
        self.data = mujoco.MjData(model)
        self.bodies: dict[int, str] = {}  # body id -> entity path (bodies with a mesh)
        self.meshes: list[GeomMesh] = []
        self.tcp_site = model.site(tcp_site).id
        for g in range(model.ngeom):
            mesh = self._geom(g)
            if mesh is not None:
                self.meshes.append(mesh)

    def _body_path(self, body: int) -> str:
        if body not in self.bodies:
            name = entity_name(self.model.body(body).name, f"body{body}")
            self.bodies[body] = "world/static" if body == 0 else f"world/{name}"
        return self.bodies[body]

    def _geom(self, g: int) -> GeomMesh | None:
        m = self.model
        kind = int(m.geom_type[g])
        if int(m.geom_group[g]) >= _VISIBLE_GROUPS or kind in (_PLANE, _HFIELD):
            return None
        matid = int(m.geom_matid[g])
        rgba = m.mat_rgba[matid] if matid >= 0 else m.geom_rgba[g]
        if float(rgba[3]) <= 0.0:
            return None
        shape = _shape(m, g, kind)
        if shape is None:
            return None
        vertices, faces = shape
        R = np.zeros(9)
        self._mj.mju_quat2Mat(R, m.geom_quat[g])
        vertices = vertices @ R.reshape(3, 3).T + m.geom_pos[g]
        body = int(m.geom_bodyid[g])
        name = entity_name(m.geom(g).name, f"geom{g}")
        color = (float(rgba[0]), float(rgba[1]), float(rgba[2]), float(rgba[3]))
        return GeomMesh(f"{self._body_path(body)}/{name}", vertices, faces, color)

    def posed(self, qpos: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The world pose (4x4) of every body with a mesh (by entity path, the world body
        left out: its meshes are already in the world frame) and the TCP pose."""
        m, d = self.model, self.data
        d.qpos[: len(qpos)] = qpos
        self._mj.mj_kinematics(m, d)
        poses = {}
        for body, path in self.bodies.items():
            if body == 0:
                continue
            T = np.eye(4)
            T[:3, :3] = d.xmat[body].reshape(3, 3)
            T[:3, 3] = d.xpos[body]
            poses[path] = T
        return poses, self.tcp_of(d)

    def tcp_of(self, d: Any) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = d.site_xmat[self.tcp_site].reshape(3, 3)
        T[:3, 3] = d.site_xpos[self.tcp_site]
        return T

    def tcp_path_m(self, qpos: np.ndarray, q_arm_rad: np.ndarray) -> np.ndarray:
        """TCP positions (N x 3, m) of the arm along joint rows ``q_arm_rad`` (N x 6), the
        rest of the state at ``qpos``."""
        m, d = self.model, self.data
        d.qpos[: len(qpos)] = qpos
        out = np.empty((len(q_arm_rad), 3))
        for i, q in enumerate(q_arm_rad):
            d.qpos[:6] = q
            self._mj.mj_kinematics(m, d)
            out[i] = d.site_xpos[self.tcp_site]
        return out


def _shape(m: Any, g: int, kind: int) -> tuple[np.ndarray, np.ndarray] | None:
    size = m.geom_size[g]
    if kind == _BOX:
        return box_mesh(np.asarray(size, float))
    if kind == _SPHERE:
        return ellipsoid_mesh(np.full(3, float(size[0])))
    if kind == _ELLIPSOID:
        return ellipsoid_mesh(np.asarray(size, float))
    if kind == _CYLINDER:
        return cylinder_mesh(float(size[0]), float(size[1]))
    if kind == _CAPSULE:  # drawn as its cylinder and two end caps
        r, h = float(size[0]), float(size[1])
        v1, f1 = cylinder_mesh(r, h)
        v2, f2 = ellipsoid_mesh(np.full(3, r))
        v3 = v2 + [0, 0, h]
        v4 = v2 - [0, 0, h]
        n1, n2 = len(v1), len(v2)
        return np.vstack([v1, v3, v4]), np.vstack([f1, f2 + n1, f2 + n1 + n2])
    if kind == _MESH:
        mesh = int(m.geom_dataid[g])
        v0, nv = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
        f0, nf = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
        vertices = np.array(m.mesh_vert[v0 : v0 + nv], float)
        faces = np.array(m.mesh_face[f0 : f0 + nf], np.uint32)
        return vertices, faces
    return None


def box_mesh(half_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A box of half sizes ``half_m`` (m), 8 vertices, 12 triangles, outward faces."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # -x, +x
            [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # -y, +y
            [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # -z, +z
        ],
        np.uint32,
    )  # fmt: skip
    return corners * half_m, faces


def cylinder_mesh(radius_m: float, half_height_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder along z, ``_SEGMENTS`` facets around."""
    a = np.linspace(0.0, 2 * np.pi, _SEGMENTS, endpoint=False)
    ring = np.stack([radius_m * np.cos(a), radius_m * np.sin(a)], axis=1)
    bottom = np.hstack([ring, np.full((_SEGMENTS, 1), -half_height_m)])
    top = np.hstack([ring, np.full((_SEGMENTS, 1), half_height_m)])
    centres = np.array([[0, 0, -half_height_m], [0, 0, half_height_m]])
    vertices = np.vstack([bottom, top, centres])
    n, cb, ct = _SEGMENTS, 2 * _SEGMENTS, 2 * _SEGMENTS + 1
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [[i, j, n + j], [i, n + j, n + i], [cb, j, i], [ct, n + i, n + j]]
    return vertices, np.array(faces, np.uint32)


def ellipsoid_mesh(radii_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A latitude-longitude ellipsoid of semi-axes ``radii_m``."""
    rings, n = _SEGMENTS // 2, _SEGMENTS
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    vertices = (unit.reshape(-1, 3)) * radii_m
    faces = []
    for r in range(rings):
        for i in range(n):
            j = (i + 1) % n
            a, b, c, d = r * n + i, r * n + j, (r + 1) * n + i, (r + 1) * n + j
            faces += [[a, c, d], [a, d, b]]
    return vertices, np.array(faces, np.uint32)
