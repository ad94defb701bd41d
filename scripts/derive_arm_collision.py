#!/usr/bin/env python3
"""Derive the arm collision geometry from Universal Robots' collision meshes.

For every UR model with published collision meshes this writes
``cellrunner/model/arm_geometry/<model>.json.gz`` (read by :mod:`cellrunner.model.arm_geometry`):

1. Meshes and frames. e-Series, UR20 and UR30: Universal Robots' ROS 2 description (a git
   directory, ``--ros2-description``; the configs' kinematics, the collision origins of
   ``urdf/ur_macro.xacro`` and ``config/<model>/visual_parameters.yaml``). CB3 (UR3, UR5,
   UR10): the URDFs and meshes of the installed ``example-robot-data`` package, loaded with
   pinocchio. Each mesh is carried into the frame of our joint (``ArmKinematics``: "DH frame
   i-1 turned by joint i"), and the transform is checked to be the same at random
   configurations (the description's chain and ours agree).
2. Parts. Each connected component of a link's mesh gets its convex hull; a component that is
   not convex (its hull stands off the mesh by more than ``--split-mm``) is cut into slabs
   along its long axis, each slab's hull taken over the surface inside the slab (the cut
   points included, so the slabs' hulls still contain the solid). Components inside another
   part are dropped. Each hull is then replaced by an intersection of few of its supporting
   half-spaces (``--simplify-mm``, at most ``--max-vertices`` vertices): always a superset.
3. Over-approximation: points sampled on the outer surface of each link's parts, and their
   distance to the link's mesh (median and max mm per link and model).
4. Self-collision pairs, for every two parts of different links, over the joints' whole
   ranges (+-180 deg covers every pose). Adjacent links: their distance at 4096 angles of
   the joint between them, the smallest and largest, and bounds (+- half a step's motion);
   a pair that stays within the clearance at every angle is the joint itself (the meshes
   meet there by construction) and is not checked. Other pairs get a lower bound of their
   distance by branch and bound over the joints between the links: the distance at a box's
   centre less ``sum_j h_j R_j`` (half-widths times the bound on the moving part's distance
   from joint j's axis) holds in the whole box. Pairs that touch somewhere, or exhaust the
   budget, get no bound: always checked.

Usage::

    python scripts/derive_arm_collision.py --ros2-description PATH/TO/GITDIR [--models ur5e]
    python scripts/derive_arm_collision.py ... --test-points tests/data/arm_surface_points

The meshes are read, never copied; only the derived parts (and, with ``--test-points``,
points sampled on the meshes' surfaces for the tests) are written.
"""

from __future__ import annotations

import argparse
import gzip
import itertools
import json
import math
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cellrunner.model.arm_geometry import LINK_NAMES  # noqa: E402
from cellrunner.model.geometry import pose_matrix  # noqa: E402
from cellrunner.model.robots import ROBOTS, RobotSpec  # noqa: E402
from cellrunner.planning.kinematics import ArmKinematics  # noqa: E402
from cellrunner.planning.motion_bounds import joint_reach  # noqa: E402
from cellrunner.planning.stl import read_stl  # noqa: E402

ROS2_REPO = "UniversalRobots/Universal_Robots_ROS2_Description"
CB3_FROM_EXAMPLE_ROBOT_DATA = ("ur3", "ur5", "ur10")
ROS2_MODELS = ("ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30")
URDF_LINKS = (
    "base_link_inertia",
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
)
FRAME_CHECK_MAX_M = 1e-5
INFLATE_M = 1e-6  # supporting planes pushed out by this much: rounding never cuts the mesh


@dataclass
class LinkMesh:
    body: int
    vertices_m: np.ndarray  # in our joint frame
    triangles: np.ndarray
    source_path: str


# -- frames -------------------------------------------------------------------------------


def rpy_matrix(xyz: list[float], rpy: list[float]) -> np.ndarray:
    """URDF origin: translation xyz, rotation Rz(yaw) Ry(pitch) Rx(roll) in radians."""
    return pose_matrix(xyz, np.degrees(rpy))


def rot_z(q: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(q), -math.sin(q)], [math.sin(q), math.cos(q)]]
    return T


def our_joint_frames(spec: RobotSpec, q: np.ndarray, T_world_base: np.ndarray) -> list[np.ndarray]:
    """World frames of our bodies 0..6 at q (body 0: the base frame)."""
    import pinocchio as pin

    kin = ArmKinematics(spec, T_world_base, np.eye(4))
    data = kin.model.createData()
    pin.forwardKinematics(kin.model, data, q)
    return [T_world_base.copy()] + [data.oMi[j].homogeneous.copy() for j in range(1, 7)]


def constant_offset(frames_ours, frames_theirs, vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """T_ours_theirs from the first configuration, and how far (m) any vertex would move
    under the other configurations' T_ours_theirs (0 when the chains agree)."""
    T0 = np.linalg.inv(frames_ours[0]) @ frames_theirs[0]
    worst = 0.0
    for ours, theirs in zip(frames_ours[1:], frames_theirs[1:], strict=True):
        T = np.linalg.inv(ours) @ theirs
        d = vertices @ (T[:3, :3] - T0[:3, :3]).T + (T[:3, 3] - T0[:3, 3])
        worst = max(worst, float(np.linalg.norm(d, axis=1).max()))
    return T0, worst


def transform(T: np.ndarray, v: np.ndarray) -> np.ndarray:
    return v @ T[:3, :3].T + T[:3, 3]


# -- sources ------------------------------------------------------------------------------


class Ros2Description:
    """Universal Robots' ROS 2 description, read from a git directory at one commit."""

    def __init__(self, gitdir: Path, commit: str):
        self.gitdir = gitdir
        self.commit = self._git("rev-parse", commit).decode().strip()

    def _git(self, *args: str) -> bytes:
        return subprocess.run(
            ["git", "--git-dir", str(self.gitdir), *args], check=True, capture_output=True
        ).stdout

    def read(self, path: str) -> bytes:
        return self._git("show", f"{self.commit}:{path}")

    def yaml(self, path: str) -> Any:
        from ruamel.yaml import YAML

        return YAML(typ="safe").load(self.read(path))

    def links(self, spec: RobotSpec) -> tuple[list[LinkMesh], dict[str, Any]]:
        name = spec.name
        kinematics = self.yaml(f"config/{name}/default_kinematics.yaml")["kinematics"]
        offsets = self.yaml(f"config/{name}/physical_parameters.yaml")["offsets"]
        visual = self.yaml(f"config/{name}/visual_parameters.yaml")["mesh_files"]
        macro = ET.fromstring(self.read("urdf/ur_macro.xacro"))
        origins = _xacro_collision_origins(macro, offsets, visual)
        fixed = _xacro_fixed_joints(macro)
        T_baselink_base = fixed["base_link-base_fixed_joint"]
        T_baselink_inertia = fixed["base_link-base_link_inertia"]
        keys = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
        joint_origins = [
            rpy_matrix(
                [kinematics[k]["x"], kinematics[k]["y"], kinematics[k]["z"]],
                [kinematics[k]["roll"], kinematics[k]["pitch"], kinematics[k]["yaw"]],
            )
            for k in keys
        ]
        meshes = {}
        paths = {}
        for body, link in enumerate(("base", *keys)):
            path = visual[link]["collision"]["mesh"]["path"]
            paths[LINK_NAMES[body]] = path
            meshes[body] = _stl_from_bytes(self.read(path))
        # URDF world = base_link; our base frame = the URDF's "base" frame
        T_world_base = T_baselink_base
        rng = np.random.default_rng(1)
        qs = [np.zeros(6)] + [rng.uniform(-math.pi, math.pi, 6) for _ in range(12)]
        ours = [our_joint_frames(spec, q, T_world_base) for q in qs]
        theirs = []
        for q in qs:
            T = T_baselink_inertia
            frames = [T]
            for j in range(6):
                T = T @ joint_origins[j] @ rot_z(q[j])
                frames.append(T)
            theirs.append(frames)
        out, worst_all = [], 0.0
        for body in range(7):
            v, t = meshes[body]
            T_link_mesh = origins[URDF_LINKS[body]]
            v_link = transform(T_link_mesh, v)
            T, worst = constant_offset([o[body] for o in ours], [f[body] for f in theirs], v_link)
            worst_all = max(worst_all, worst)
            out.append(LinkMesh(body, transform(T, v_link), t, paths[LINK_NAMES[body]]))
        if worst_all > FRAME_CHECK_MAX_M:
            raise SystemExit(
                f"{name}: the description's chain and ours disagree by {worst_all * 1000:.3f} mm"
            )
        source = {
            "repo": ROS2_REPO,
            "commit": self.commit,
            "paths": paths,
            "frames": "urdf/ur_macro.xacro collision origins, config/"
            f"{name}/default_kinematics.yaml; checked against our FK at 13 configurations "
            f"(largest disagreement {worst_all * 1000:.4f} mm)",
        }
        return out, source


def _stl_from_bytes(raw: bytes) -> tuple[np.ndarray, np.ndarray]:
    import tempfile

    with tempfile.NamedTemporaryFile(suffix=".stl") as f:
        f.write(raw)
        f.flush()
        return read_stl(Path(f.name))


def _xacro_value(text: str, names: dict[str, float]) -> list[float]:
    """'0 0 ${shoulder_offset}' -> numbers (the ``${...}`` parts evaluated)."""
    out = []
    for token in text.split():
        if token.startswith("${") and token.endswith("}"):
            out.append(float(eval(token[2:-1], {"__builtins__": {}}, names)))
        else:
            out.append(float(token))
    return out


def _xacro_collision_origins(
    macro: ET.Element, offsets: dict[str, float], visual: dict[str, Any]
) -> dict[str, np.ndarray]:
    origins = {}
    for link in macro.iter("link"):
        name = link.get("name", "").replace("${tf_prefix}", "")
        origin = link.find("collision/origin")
        if name not in URDF_LINKS or origin is None:
            continue
        key = {"base_link_inertia": "base"}.get(name, name.removesuffix("_link"))
        names = {
            "pi": math.pi,
            "shoulder_offset": float(offsets["shoulder_offset"]),
            "elbow_offset": float(offsets["elbow_offset"]),
            "visual_params": float(visual[key].get("visual_offset", 0.0)),
        }
        origins[name] = rpy_matrix(
            _xacro_value(origin.get("xyz", "0 0 0"), names),
            _xacro_value(origin.get("rpy", "0 0 0"), names),
        )
    missing = set(URDF_LINKS) - set(origins)
    if missing:
        raise SystemExit(f"ur_macro.xacro: no collision origin for {sorted(missing)}")
    return origins


def _xacro_fixed_joints(macro: ET.Element) -> dict[str, np.ndarray]:
    out = {}
    for joint in macro.iter("joint"):
        origin = joint.find("origin")
        if (
            joint.get("type") == "fixed"
            and origin is not None
            and "${" not in origin.get("xyz", "")
        ):
            name = joint.get("name", "").replace("${tf_prefix}", "")
            names = {"pi": math.pi}
            out[name] = rpy_matrix(
                _xacro_value(origin.get("xyz", "0 0 0"), names),
                _xacro_value(origin.get("rpy", "0 0 0"), names),
            )
    return out


def example_robot_data_share() -> Path:
    """The ``share`` folder of the installed example-robot-data package."""
    dist = metadata.distribution("example-robot-data")
    for f in dist.files or ():
        if str(f).endswith("ur_description/urdf/ur5_robot.urdf"):
            return Path(dist.locate_file(f)).parents[4]
    raise SystemExit("example-robot-data is installed without the UR descriptions")


def cb3_urdf(model: str) -> Path:
    return (
        example_robot_data_share()
        / "example-robot-data/robots/ur_description/urdf"
        / f"{model}_robot.urdf"
    )


def cb3_links(spec: RobotSpec) -> tuple[list[LinkMesh], dict[str, Any]]:
    """The CB3 collision meshes of example-robot-data in our joint frames (the URDF loaded
    with pinocchio; its ``base`` frame is our base frame)."""
    import pinocchio as pin

    share = example_robot_data_share()
    urdf = cb3_urdf(spec.name)
    model = pin.buildModelFromUrdf(str(urdf))
    geoms = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, str(share))
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(model.nq))
    T_world_base = data.oMf[model.getFrameId("base")].homogeneous.copy()
    order = [
        model.getJointId(f"{j}_joint")
        for j in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    ]
    body_of_joint = {0: 0, **{jid: i + 1 for i, jid in enumerate(order)}}
    rng = np.random.default_rng(1)
    qs = [np.zeros(6)] + [rng.uniform(-math.pi, math.pi, 6) for _ in range(12)]
    ours = [our_joint_frames(spec, q, T_world_base) for q in qs]
    theirs = []
    for q in qs:
        qu = np.zeros(model.nq)
        for i, jid in enumerate(order):
            qu[model.joints[jid].idx_q] = q[i]
        pin.forwardKinematics(model, data, qu)
        theirs.append({jid: data.oMi[jid].homogeneous.copy() for jid in range(model.njoints)})
    out, paths, worst_all = [], {}, 0.0
    version = metadata.version("example-robot-data")
    for g in geoms.geometryObjects:
        if not g.meshPath.endswith(".stl"):
            continue  # the URDF's ee_link box is no part of the arm
        body = body_of_joint[g.parentJoint]
        v, t = read_stl(Path(g.meshPath))
        v = v * np.asarray(g.meshScale)
        v_joint = transform(g.placement.homogeneous, v)
        T, worst = constant_offset(
            [o[body] for o in ours], [f[g.parentJoint] for f in theirs], v_joint
        )
        worst_all = max(worst_all, worst)
        rel = str(Path(g.meshPath).relative_to(share))
        paths[LINK_NAMES[body]] = rel
        out.append(LinkMesh(body, transform(T, v_joint), t, rel))
    if worst_all > FRAME_CHECK_MAX_M or sorted(m.body for m in out) != list(range(7)):
        raise SystemExit(f"{spec.name}: URDF chain disagrees with ours ({worst_all} m)")
    source = {
        "package": "example-robot-data",
        "version": version,
        "urdf": str(urdf.relative_to(share)),
        "paths": paths,
        "upstream": "ros-industrial/universal_robot (ur_description, CB3 collision meshes)",
        "frames": "URDF loaded with pinocchio, frame 'base' = our base; checked against our "
        f"FK at 13 configurations (largest disagreement {worst_all * 1000:.4f} mm)",
    }
    return sorted(out, key=lambda m: m.body), source


# -- parts --------------------------------------------------------------------------------


def mesh_components(v: np.ndarray, t: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The connected components of a triangle mesh (vertices, triangles reindexed)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(v)
    rows = np.r_[t[:, 0], t[:, 1], t[:, 2]]
    cols = np.r_[t[:, 1], t[:, 2], t[:, 0]]
    count, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), (n, n)))
    out = []
    for c in range(count):
        tc = t[label[t[:, 0]] == c]
        used = np.unique(tc)
        remap = np.full(n, -1)
        remap[used] = np.arange(len(used))
        out.append((v[used], remap[tc]))
    return out


def hull_points(points: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``points``; a flat set is thickened by 10 um
    across its plane (still containing it)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        h = ConvexHull(points)
        if h.volume > 1e-12:
            return points[h.vertices]
    except QhullError:
        pass
    centered = points - points.mean(axis=0)
    normal = np.linalg.svd(centered, full_matrices=False)[2][-1]
    thick = np.concatenate([points + 1e-5 * normal, points - 1e-5 * normal])
    return thick[ConvexHull(thick).vertices]


def slab_points(v: np.ndarray, t: np.ndarray, axis: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """The corners of the surface's part between the planes axis.x = lo and = hi: vertices
    in the slab and the points where edges cross its planes (their hull holds the solid's
    part in the slab)."""
    s = v @ axis
    inside = v[(s >= lo) & (s <= hi)]
    edges = np.unique(np.sort(np.r_[t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1), axis=0)
    a, b = edges[:, 0], edges[:, 1]
    cuts = [inside]
    for plane in (lo, hi):
        cross = (s[a] - plane) * (s[b] - plane) < 0
        f = (plane - s[a][cross]) / (s[b][cross] - s[a][cross])
        cuts.append(v[a][cross] + f[:, None] * (v[b][cross] - v[a][cross]))
    return np.concatenate(cuts)


class MeshDistance:
    """Unsigned distance (m) from points to a triangle mesh's surface (coal, exact)."""

    def __init__(self, v: np.ndarray, t: np.ndarray):
        import coal

        self._coal = coal
        self.bvh = coal.BVHModelOBBRSS()
        self.bvh.beginModel(len(t), len(v))
        self.bvh.addVertices(np.ascontiguousarray(v, float))
        self.bvh.addTriangles(np.ascontiguousarray(t, np.int64))
        self.bvh.endModel()
        self.point = coal.Sphere(1e-9)
        self.request = coal.DistanceRequest()

    def __call__(self, points: np.ndarray) -> np.ndarray:
        coal = self._coal
        out = np.empty(len(points))
        identity = coal.Transform3s()
        for i, p in enumerate(points):
            T = coal.Transform3s()
            T.setTranslation(p)
            result = coal.DistanceResult()
            out[i] = coal.distance(self.point, T, self.bvh, identity, self.request, result)
        return np.maximum(out + 1e-9, 0.0)


def surface_samples(vertices: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform by area on the hull of ``vertices``."""
    from scipy.spatial import ConvexHull

    h = ConvexHull(vertices)
    tri = vertices[h.simplices]
    return triangle_samples(tri, n, rng)


def triangle_samples(tri: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    pick = rng.choice(len(tri), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    t = tri[pick]
    return t[:, 0] + r1[:, None] * (t[:, 1] - t[:, 0]) + r2[:, None] * (t[:, 2] - t[:, 0])


def inside_hull(points: np.ndarray, vertices: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    from scipy.spatial import ConvexHull

    eq = ConvexHull(vertices).equations
    return (points @ eq[:, :3].T + eq[:, 3]).max(axis=1) <= tol


def split_component(
    v: np.ndarray, t: np.ndarray, split_m: float, rng: np.random.Generator
) -> list[np.ndarray]:
    """Hull point sets covering one mesh component: its hull, or, where that stands off
    the surface by more than ``split_m``, the hulls of 2, 3 or 4 equal slabs along
    its long axis (the first count that meets ``split_m``, else the last)."""
    hull = hull_points(v)
    if len(t) < 8:
        return [hull]
    distance = MeshDistance(v, t)
    if union_gaps([hull], distance, rng, 400).max() <= split_m:
        return [hull]
    axis = np.linalg.svd(v - v.mean(axis=0), full_matrices=False)[2][0]
    s = v @ axis
    pieces = [hull]
    for n in (2, 3, 4):
        cuts = np.linspace(s.min(), s.max(), n + 1)
        cuts[0], cuts[-1] = s.min() - 1.0, s.max() + 1.0
        pieces = [
            hull_points(slab_points(v, t, axis, lo, hi)) for lo, hi in itertools.pairwise(cuts)
        ]
        if union_gaps(pieces, distance, rng, 400 * n).max() <= split_m:
            break
    return pieces


def union_gaps(
    parts: list[np.ndarray], distance: MeshDistance, rng: np.random.Generator, n: int
) -> np.ndarray:
    """Distances (m) to the mesh of points sampled on the outer surface of the parts' union
    (points of one part's surface inside another part are not on it)."""
    total = []
    for i, p in enumerate(parts):
        pts = surface_samples(p, n // len(parts) + 1, rng)
        outer = np.ones(len(pts), bool)
        for j, o in enumerate(parts):
            if j != i:
                outer &= ~inside_hull(pts, o, tol=-1e-6)
        total.append(pts[outer])
    return distance(np.concatenate(total))


def simplify(points: np.ndarray, tol_m: float, max_vertices: int) -> np.ndarray:
    """Vertices of an intersection of supporting half-spaces of hull(points) (a superset):
    planes are added at the hull's facet most violated by the current polytope until it
    stands off the hull by at most ``tol_m`` or would get more than ``max_vertices``."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    hull = ConvexHull(points)
    eq = hull.equations
    centre = points[hull.vertices].mean(axis=0)
    dirs = [np.eye(3)[i] * s for i in range(3) for s in (1, -1)]
    dirs += [np.array([a, b, c]) / math.sqrt(3) for a in (1, -1) for b in (1, -1) for c in (1, -1)]
    normals = list(dirs)

    def polytope(ns: list[np.ndarray]) -> np.ndarray:
        n = np.array(ns)
        h = (points @ n.T).max(axis=0) + INFLATE_M
        hs = HalfspaceIntersection(np.c_[n, -h], centre).intersections
        return hs[ConvexHull(hs).vertices]

    best = polytope(normals)
    for _ in range(400):
        off = best @ eq[:, :3].T + eq[:, 3]
        worst = off.max()
        if worst <= tol_m:
            break
        facet = int(np.unravel_index(off.argmax(), off.shape)[1])
        candidate = polytope([*normals, eq[facet, :3]])
        if len(candidate) > max_vertices:
            break
        normals.append(eq[facet, :3])
        best = candidate
    return best


def merge_parts(
    parts: list[np.ndarray], distance: MeshDistance, merge_m: float, rng: np.random.Generator
) -> list[np.ndarray]:
    """Greedily replace two parts by the hull of both where that hull's outer surface stands
    off the link's mesh by at most ``merge_m`` (fewer parts, no looser than asked)."""
    parts = list(parts)
    while len(parts) > 1:
        volume = [hull_volume(p) for p in parts]
        merged = False
        for i in sorted(range(len(parts)), key=lambda i: volume[i]):
            centre = parts[i].mean(axis=0)
            others = sorted(
                (j for j in range(len(parts)) if j != i),
                key=lambda j: np.linalg.norm(parts[j].mean(axis=0) - centre),
            )
            for j in others[:3]:
                union = hull_points(np.concatenate([parts[i], parts[j]]))
                rest = [p for k, p in enumerate(parts) if k not in (i, j)]
                pts = surface_samples(union, 600, rng)
                for o in rest:
                    pts = pts[~inside_hull(pts, o, tol=-1e-6)]
                if len(pts) == 0 or distance(pts).max() <= merge_m:
                    parts = [*rest, union]
                    merged = True
                    break
            if merged:
                break
        if not merged:
            break
    return parts


def hull_volume(points: np.ndarray) -> float:
    from scipy.spatial import ConvexHull

    return float(ConvexHull(points).volume)


def derive_parts(
    link: LinkMesh, split_m: float, tol_m: float, max_vertices: int, rng: np.random.Generator
) -> list[np.ndarray]:
    comps = mesh_components(link.vertices_m, link.triangles)
    hulls: list[np.ndarray] = []
    for v, t in comps:
        hulls += split_component(v, t, split_m, rng)
    # drop hulls inside another one
    keep: list[np.ndarray] = []
    for i, h in enumerate(hulls):
        inside_other = any(
            j != i and inside_hull(h, o).all() and (j < i or not inside_hull(o, h).all())
            for j, o in enumerate(hulls)
        )
        if not inside_other:
            keep.append(h)
    keep = merge_parts(keep, MeshDistance(link.vertices_m, link.triangles), split_m, rng)
    return [simplify(h, tol_m, max_vertices) for h in keep]


def over_approximation(
    link: LinkMesh, parts: list[np.ndarray], rng: np.random.Generator, n: int = 3000
) -> np.ndarray:
    """Distances (m) from points on the outer surface of the parts' union to the mesh."""
    return union_gaps(parts, MeshDistance(link.vertices_m, link.triangles), rng, n)


def check_containment(link: LinkMesh, parts: list[np.ndarray], rng: np.random.Generator) -> float:
    """Largest distance (m) by which a mesh vertex or surface sample lies outside every part."""
    from scipy.spatial import ConvexHull

    pts = np.concatenate(
        [link.vertices_m, triangle_samples(link.vertices_m[link.triangles], 5000, rng)]
    )
    worst = np.full(len(pts), np.inf)
    for p in parts:
        eq = ConvexHull(p).equations
        worst = np.minimum(worst, (pts @ eq[:, :3].T + eq[:, 3]).max(axis=1))
    return float(worst.max())


# -- self-collision pairs -----------------------------------------------------------------


class PairProver:
    """Lower bounds of part distances over the joint ranges (see the module docstring)."""

    def __init__(self, spec: RobotSpec, parts: list[tuple[int, np.ndarray]]):
        import coal

        self.coal = coal
        kin = ArmKinematics(spec, np.eye(4), np.eye(4))
        self.model = kin.model
        self.placements = [kin.model.jointPlacements[j].homogeneous for j in range(1, 7)]
        self.parts = parts
        self.geoms = []
        for _, v in parts:
            vec = coal.StdVec_Vec3s()
            vec.extend([np.asarray(x, float) for x in v])
            self.geoms.append(coal.Convex.convexHull(vec, False, ""))
        self.request = coal.DistanceRequest()

    def relative(self, a: int, b: int, q: np.ndarray) -> np.ndarray:
        """T_bodyA_bodyB with joints a+1..b at q (len b - a)."""
        T = np.eye(4)
        for k, j in enumerate(range(a + 1, b + 1)):
            P = self.placements[j - 1] if j > 1 else np.eye(4)
            T = T @ P @ rot_z(q[k])
        return T

    def distance(self, i: int, k: int, T_ab: np.ndarray) -> float:
        coal = self.coal
        Tb = coal.Transform3s()
        Tb.setRotation(T_ab[:3, :3])
        Tb.setTranslation(T_ab[:3, 3])
        result = coal.DistanceResult()
        return float(
            coal.distance(
                self.geoms[i], coal.Transform3s(), self.geoms[k], Tb, self.request, result
            )
        )

    def reach(self, k: int) -> np.ndarray:
        body, v = self.parts[k]
        return joint_reach(self.model, body, v, 0.0)

    def adjacent(self, i: int, k: int, samples: int) -> tuple[float, float, float, float]:
        """Parts of adjacent links over their joint's whole turn: (lower bound, smallest
        sampled, largest sampled, upper bound) of their distance (m)."""
        a, b = self.parts[i][0], self.parts[k][0]
        angles = np.linspace(-math.pi, math.pi, samples, endpoint=False)
        d = np.array([self.distance(i, k, self.relative(a, b, [x])) for x in angles])
        slack = math.pi / samples * float(self.reach(k)[b - 1])  # half a step's motion
        return float(d.min() - slack), float(d.min()), float(d.max()), float(d.max() + slack)

    def prove(
        self, i: int, k: int, rng: np.random.Generator, budget: int
    ) -> tuple[float | None, float]:
        """(a lower bound of the pair's distance over the joint ranges, None when the parts
        can touch or the budget runs out; the smallest distance seen). Branch and bound:
        boxes whose bound reaches ``target`` (a little under the smallest distance seen)
        are done; the others are split along the joint that moves the part most."""
        a, b = self.parts[i][0], self.parts[k][0]
        dims = b - a
        R = self.reach(k)[a:b]  # joints a+1..b
        seen = math.inf
        for _ in range(300):
            seen = min(seen, self.distance(i, k, self.relative(a, b, rng.uniform(-3.2, 3.2, dims))))
            if seen <= 0.0:
                return None, seen
        boxes = [(np.zeros(dims), np.full(dims, math.pi))]
        proven = math.inf
        for _ in range(budget):
            if not boxes:
                return proven, seen
            centre, half = boxes.pop()
            d = self.distance(i, k, self.relative(a, b, centre))
            seen = min(seen, d)
            if seen <= 0.0:
                return None, seen
            target = seen - min(0.5 * seen, 0.003)
            bound = d - float(half @ R)
            if bound >= target:
                proven = min(proven, bound)
                continue
            j = int(np.argmax(half * R))
            half = half.copy()
            half[j] /= 2
            for s in (-1, 1):
                c = centre.copy()
                c[j] += s * half[j]
                boxes.append((c, half))
        return None, seen


def self_pairs(
    spec: RobotSpec,
    parts_by_link: dict[int, list[np.ndarray]],
    budget: int,
    rng: np.random.Generator,
) -> list[dict[str, Any]]:
    flat = [(body, v) for body in range(7) for v in parts_by_link[body]]
    index = [(body, k) for body in range(7) for k in range(len(parts_by_link[body]))]
    prover = PairProver(spec, flat)
    out = []
    for i in range(len(flat)):
        for k in range(i + 1, len(flat)):
            a, b = flat[i][0], flat[k][0]
            if a == b:
                continue
            entry: dict[str, Any] = {
                "a": [LINK_NAMES[a], index[i][1]],
                "b": [LINK_NAMES[b], index[k][1]],
            }
            if b == a + 1:
                lower, seen, largest, upper = prover.adjacent(i, k, 4096)
                entry["adjacent"] = True
                entry["lower_bound_m"] = round(lower, 6)
                entry["max_sampled_m"] = round(largest, 6)
                entry["upper_bound_m"] = round(upper, 6)
            else:
                bound, seen = prover.prove(i, k, rng, budget)
                entry["adjacent"] = False
                entry["lower_bound_m"] = None if bound is None else round(bound, 6)
            entry["min_sampled_m"] = round(seen, 6)
            out.append(entry)
    return out


# -- main ---------------------------------------------------------------------------------


def derive(
    spec: RobotSpec, links: list[LinkMesh], source: dict[str, Any], args: argparse.Namespace
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    rng = np.random.default_rng(7)
    t0 = time.monotonic()
    doc_links = []
    parts_by_link: dict[int, list[np.ndarray]] = {}
    all_gaps = []
    per_link = {}
    for link in links:
        parts = derive_parts(
            link, args.split_mm / 1000, args.simplify_mm / 1000, args.max_vertices, rng
        )
        outside = check_containment(link, parts, rng)
        if outside > 1e-7:
            raise SystemExit(
                f"{spec.name} {LINK_NAMES[link.body]}: mesh outside parts by {outside} m"
            )
        gaps = over_approximation(link, parts, rng)
        all_gaps.append(gaps)
        per_link[LINK_NAMES[link.body]] = {
            "median": round(float(np.median(gaps)) * 1000, 2),
            "max": round(float(gaps.max()) * 1000, 2),
            "parts": len(parts),
            "vertices": [len(p) for p in parts],
        }
        parts_by_link[link.body] = parts
        doc_links.append({"name": LINK_NAMES[link.body], "parts": [_part_doc(p) for p in parts]})
        print(
            f"  {spec.name} {LINK_NAMES[link.body]}: {per_link[LINK_NAMES[link.body]]}", flush=True
        )
    gaps = np.concatenate(all_gaps)
    pairs = self_pairs(spec, parts_by_link, args.budget, rng)
    doc = {
        "model": spec.name,
        "format": 1,
        "frames": "parts of link i in the frame of pinocchio joint i of ArmKinematics (DH frame "
        "i-1 turned by joint i); link 0 in the base frame",
        "source": source,
        "derivation": {
            "script": "scripts/derive_arm_collision.py",
            "split_mm": args.split_mm,
            "simplify_mm": args.simplify_mm,
            "max_vertices": args.max_vertices,
        },
        "over_approximation_mm": {
            "median": round(float(np.median(gaps)) * 1000, 2),
            "max": round(float(gaps.max()) * 1000, 2),
            "measured": "distance to the mesh of points sampled on the parts' outer surface",
            "links": per_link,
        },
        "links": doc_links,
        "self_collision": {
            "rule": "a pair of parts of different links is checked at a clearance c unless its "
            "proven lower bound over the joint ranges exceeds c, or the links are adjacent and "
            "the pair is within c at every sampled angle of their joint (the joint itself: "
            "max_sampled_m <= c)",
            "pairs": pairs,
        },
        "seconds": round(time.monotonic() - t0, 1),
    }
    points = {
        LINK_NAMES[link.body]: triangle_samples(link.vertices_m[link.triangles], 2000, rng)
        for link in links
    }
    return doc, points


def _part_doc(vertices: np.ndarray) -> dict[str, Any]:
    from scipy.spatial import ConvexHull

    h = ConvexHull(vertices)
    v = vertices[h.vertices]
    remap = {int(k): i for i, k in enumerate(h.vertices)}
    faces = [[remap[int(x)] for x in tri] for tri in h.simplices]
    # outward winding
    centre = v.mean(axis=0)
    for f in faces:
        a, b, c = v[f[0]], v[f[1]], v[f[2]]
        if np.dot(np.cross(b - a, c - a), a - centre) < 0:
            f[1], f[2] = f[2], f[1]
    return {
        "vertices_m": np.round(v, 7).tolist(),
        "faces": faces,
        "volume_m3": float(h.volume),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ros2-description", type=Path, help="git directory of " + ROS2_REPO)
    parser.add_argument("--commit", default="HEAD")
    parser.add_argument("--models", nargs="*", default=[*CB3_FROM_EXAMPLE_ROBOT_DATA, *ROS2_MODELS])
    parser.add_argument("--out", type=Path, default=ROOT / "cellrunner/model/arm_geometry")
    parser.add_argument("--test-points", type=Path, help="write mesh surface samples here")
    parser.add_argument("--split-mm", type=float, default=3.0)
    parser.add_argument("--simplify-mm", type=float, default=1.0)
    parser.add_argument("--max-vertices", type=int, default=128)
    parser.add_argument("--budget", type=int, default=20000, help="boxes per pair")
    args = parser.parse_args()
    ros2 = Ros2Description(args.ros2_description, args.commit) if args.ros2_description else None
    for name in args.models:
        spec = ROBOTS[name]
        if name in CB3_FROM_EXAMPLE_ROBOT_DATA:
            links, source = cb3_links(spec)
        else:
            if ros2 is None:
                raise SystemExit(f"{name}: needs --ros2-description")
            links, source = ros2.links(spec)
        print(f"{name}: {source.get('commit', source.get('version'))}", flush=True)
        doc, points = derive(spec, links, source, args)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / f"{name}.json.gz").write_bytes(
            gzip.compress(json.dumps(doc, separators=(",", ":")).encode(), mtime=0)
        )
        if args.test_points is not None and name not in CB3_FROM_EXAMPLE_ROBOT_DATA:
            args.test_points.mkdir(parents=True, exist_ok=True)
            np.savez_compressed(
                args.test_points / f"{name}.npz",
                **{k: v.astype(np.float32) for k, v in points.items()},
            )
        o = doc["over_approximation_mm"]
        checked = sum(1 for p in doc["self_collision"]["pairs"] if p["lower_bound_m"] is None)
        print(
            f"{name}: over-approximation median {o['median']} mm, max {o['max']} mm; "
            f"{len(doc['self_collision']['pairs'])} part pairs, {checked} always checked; "
            f"{doc['seconds']} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
