"""The arm's convex parts against Universal Robots' collision meshes.

CB3 (UR3, UR5, UR10): the meshes of example-robot-data, placed by its URDF through
pinocchio (a chain independent of ours: only its ``base`` frame is taken as our base).
Other models: points sampled on their meshes' surfaces (``tests/data/arm_surface_points``,
written by ``scripts/derive_arm_collision.py --test-points``), in our joint frames.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from cellrunner.errors import InfeasibleError
from cellrunner.model.arm_geometry import (
    LINK_NAMES,
    ArmGeometryMissing,
    arm_geometry,
    available_models,
)
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.collision import CollisionModel
from cellrunner.planning.kinematics import ArmKinematics

CB3 = ("ur3", "ur5", "ur10")
POINTS = Path(__file__).parents[1] / "data" / "arm_surface_points"
DEG = math.pi / 180
STANDARD_POSES_DEG = ([0, -90, 0, -90, 0, 0], [0, -90, 90, -90, -90, 0])
#: folded poses: the forearm folded back over the upper arm, wrists tucked
FOLDED_POSES_DEG = (
    [0, -90, 150, -150, -90, 0],
    [0, -90, -150, 150, 90, 0],
    [90, -60, 140, -170, -90, 0],
    [0, -30, 155, -120, 90, 45],
)


def planes(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals and offsets of a part's facets (n . x <= offset inside)."""
    from scipy.spatial import ConvexHull

    eq = ConvexHull(vertices).equations
    return eq[:, :3], -eq[:, 3]


def outside_by(points: np.ndarray, parts) -> np.ndarray:
    """How far (m) each point lies outside the nearest part (<= 0: inside one)."""
    worst = np.full(len(points), np.inf)
    for part in parts:
        n, d = planes(part.vertices_m)
        worst = np.minimum(worst, (points @ n.T - d).max(axis=1))
    return worst


@cache
def cb3_meshes(model: str):
    """pinocchio model, data, collision geometry (meshes) and T_world_base of a CB3 URDF."""
    from importlib import metadata

    import pinocchio as pin

    dist = metadata.distribution("example-robot-data")
    urdf = next(
        Path(dist.locate_file(f))
        for f in dist.files or ()
        if str(f).endswith(f"ur_description/urdf/{model}_robot.urdf")
    )
    share = urdf.parents[4]
    pmodel = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(pmodel, str(urdf), pin.GeometryType.COLLISION, str(share))
    keep = [g for g in geom.geometryObjects if g.meshPath.endswith(".stl")]
    data = pmodel.createData()
    pin.framesForwardKinematics(pmodel, data, np.zeros(pmodel.nq))
    T_world_base = data.oMf[pmodel.getFrameId("base")].homogeneous.copy()
    return pmodel, keep, T_world_base


def cb3_mesh_vertices(model: str, q: np.ndarray) -> dict[int, np.ndarray]:
    """World vertices of each body's mesh (body 0..6) at controller angles q."""
    import pinocchio as pin

    from cellrunner.planning.stl import read_stl

    pmodel, geoms, _ = cb3_meshes(model)
    data = pmodel.createData()
    pin.forwardKinematics(pmodel, data, _urdf_q(pmodel, q))
    out = {}
    for g in geoms:
        body = 0 if g.parentJoint == 0 else _body_of(pmodel, g.parentJoint)
        v = read_stl(Path(g.meshPath))[0] * np.asarray(g.meshScale)
        T = data.oMi[g.parentJoint].homogeneous @ g.placement.homogeneous
        out[body] = v @ T[:3, :3].T + T[:3, 3]
    return out


def _urdf_q(pmodel, q: np.ndarray) -> np.ndarray:
    qu = np.zeros(pmodel.nq)
    for i, name in enumerate(
        ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    ):
        qu[pmodel.joints[pmodel.getJointId(f"{name}_joint")].idx_q] = q[i]
    return qu


def _body_of(pmodel, joint_id: int) -> int:
    names = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    return names.index(pmodel.names[joint_id].removesuffix("_joint")) + 1


def our_frames(model: str, q: np.ndarray, T_world_base: np.ndarray) -> list[np.ndarray]:
    import pinocchio as pin

    kin = ArmKinematics(ROBOTS[model], T_world_base, np.eye(4))
    data = kin.model.createData()
    pin.forwardKinematics(kin.model, data, q)
    return [T_world_base] + [data.oMi[j].homogeneous for j in range(1, 7)]


# -- every model --------------------------------------------------------------------------


def test_every_model_with_meshes_has_geometry_and_its_source() -> None:
    assert set(available_models()) >= {"ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e"}
    for model in available_models():
        geometry = arm_geometry(model)
        assert {p.body for p in geometry.parts} == set(range(7))
        source = geometry.source
        assert source.get("commit") or source.get("version")
        assert set(source["paths"]) == set(LINK_NAMES)


@pytest.mark.parametrize("model", sorted(set(available_models()) - set(CB3)))
def test_parts_contain_the_sampled_mesh_surface(model: str) -> None:
    stored = np.load(POINTS / f"{model}.npz")
    parts = arm_geometry(model).parts
    for body, link in enumerate(LINK_NAMES):
        points = stored[link].astype(float)
        assert len(points) == 2000
        # float32 storage rounds by < 0.1 um at these sizes
        assert outside_by(points, [p for p in parts if p.body == body]).max() <= 2e-7, link


@pytest.mark.parametrize("model", CB3)
def test_cb3_parts_contain_the_real_meshes_in_any_pose(model: str) -> None:
    """Every vertex of every example-robot-data mesh, placed by the URDF's own chain, lies
    in the parts placed by our kinematics, at random configurations."""
    _, _, T_world_base = cb3_meshes(model)
    parts = arm_geometry(model).parts
    rng = np.random.default_rng(3)
    for q in [np.zeros(6), *rng.uniform(-math.pi, math.pi, (4, 6))]:
        frames = our_frames(model, q, T_world_base)
        for body, world in cb3_mesh_vertices(model, q).items():
            T = np.linalg.inv(frames[body])
            local = world @ T[:3, :3].T + T[:3, 3]
            mine = [p for p in parts if p.body == body]
            assert outside_by(local, mine).max() <= 1e-6, (model, LINK_NAMES[body])


@pytest.mark.parametrize("model", available_models())
def test_over_approximation_is_a_few_millimetres(model: str) -> None:
    figures = arm_geometry(model).over_approximation_mm
    assert figures["median"] <= 1.0
    assert figures["max"] <= 25.0


def test_cb3_over_approximation_measured_against_the_real_mesh() -> None:
    """UR5: points on the parts' outer surface lie within the stated max of the mesh."""
    import coal

    from cellrunner.planning.stl import read_stl

    pmodel, geoms, T_world_base = cb3_meshes("ur5")
    geometry = arm_geometry("ur5")
    frames = our_frames("ur5", np.zeros(6), T_world_base)
    rng = np.random.default_rng(5)
    worst = 0.0
    for g in geoms:
        body = 0 if g.parentJoint == 0 else _body_of(pmodel, g.parentJoint)
        t = read_stl(Path(g.meshPath))[1]
        world = cb3_mesh_vertices("ur5", np.zeros(6))[body]
        T = np.linalg.inv(frames[body])
        local = world @ T[:3, :3].T + T[:3, 3]
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(t), len(local))
        bvh.addVertices(np.ascontiguousarray(local))
        bvh.addTriangles(np.ascontiguousarray(t, np.int64))
        bvh.endModel()
        parts = [p for p in geometry.parts if p.body == body]
        for part in parts:
            f = part.faces
            tri = part.vertices_m[f]
            pick = rng.choice(len(f), 200)
            r = rng.dirichlet(np.ones(3), 200)
            pts = (tri[pick] * r[:, :, None]).sum(axis=1)
            others = [p for p in parts if p is not part]
            if others:
                pts = pts[outside_by(pts, others) > -1e-6]
            for p in pts:
                tf = coal.Transform3s()
                tf.setTranslation(p)
                d = coal.distance(
                    coal.Sphere(1e-9),
                    tf,
                    bvh,
                    coal.Transform3s(),
                    coal.DistanceRequest(),
                    coal.DistanceResult(),
                )
                worst = max(worst, d)
    assert worst * 1000 <= geometry.over_approximation_mm["max"] + 1.0


def test_a_model_without_meshes_is_refused_by_name() -> None:
    spec = next((s for s in ROBOTS.values() if s.arm not in available_models()), None)
    with pytest.raises(ArmGeometryMissing, match="no collision geometry for robot model 'ur99'"):
        arm_geometry("ur99")
    if spec is None:
        return
    kin = ArmKinematics(spec, np.eye(4), np.eye(4))
    with pytest.raises(
        InfeasibleError, match=f"no collision geometry for robot model '{spec.name}'"
    ):
        CollisionModel(kin)


# -- self-collision -------------------------------------------------------------------------


def arm_only(model: str, clearance_m: float = 0.002) -> CollisionModel:
    return CollisionModel(
        ArmKinematics(ROBOTS[model], np.eye(4), np.eye(4)), clearance_m=clearance_m
    )


@pytest.mark.parametrize("model", available_models())
@pytest.mark.parametrize("pose", STANDARD_POSES_DEG)
def test_standard_poses_are_free(model: str, pose: list[float]) -> None:
    world = arm_only(model)
    q = np.radians(pose)
    assert world.is_valid(q), world.clearance(q).describe()


@pytest.mark.parametrize("model", available_models())
def test_skipped_pairs_never_come_within_the_clearance(model: str) -> None:
    """Pairs the derivation skips stay apart (or are a joint) at random configurations:
    checked with a model that checks every pair of different links."""
    geometry = arm_geometry(model)
    world = arm_only(model)
    checked = {tuple(sorted(p)) for p in world._pairs.tolist()}
    import pinocchio as pin

    rng = np.random.default_rng(11)
    parts = geometry.parts
    arm_index = {id(o.part): k for k, o in enumerate(world._objects) if o.part is not None}
    skipped = [
        (a, b)
        for a in range(len(parts))
        for b in range(a + 1, len(parts))
        if parts[a].body != parts[b].body
        and (arm_index[id(parts[a])], arm_index[id(parts[b])]) not in checked
        # not the joint between adjacent links
        and geometry.link_joint_max_m.get((parts[a].body, parts[b].body), np.inf)
        > world.clearance_m
    ]
    import coal

    for q in rng.uniform(-math.pi, math.pi, (200, 6)):
        world._update(q)
        for a, b in skipped:
            oa, ob = (
                world._objects[arm_index[id(parts[a])]],
                world._objects[arm_index[id(parts[b])]],
            )
            ga = world._geom_data.oMg[arm_index[id(parts[a])]]
            gb = world._geom_data.oMg[arm_index[id(parts[b])]]
            d = coal.distance(
                oa.geometry,
                coal.Transform3s(ga.rotation, ga.translation),
                ob.geometry,
                coal.Transform3s(gb.rotation, gb.translation),
                coal.DistanceRequest(),
                coal.DistanceResult(),
            )
            assert d > world.clearance_m, (LINK_NAMES[parts[a].body], LINK_NAMES[parts[b].body])
    del pin


@pytest.mark.parametrize("model", CB3)
@pytest.mark.parametrize("pose", STANDARD_POSES_DEG + FOLDED_POSES_DEG)
def test_cb3_poses_agree_with_the_meshes(model: str, pose: list[float]) -> None:
    """Where the meshes of non-adjacent links stay apart by the clearance plus the stated
    over-approximation the parts accept; where they interpenetrate the parts refuse."""
    q = np.radians(pose)
    d = mesh_pair_distances(model, q)
    apart, penetrating = min(d.values()), any(v < 0 for v in d.values())
    world = arm_only(model)
    slack = world.clearance_m + arm_geometry(model).over_approximation_mm["max"] / 1000
    if penetrating:
        assert not world.is_valid(q)
    elif apart >= slack:
        assert world.is_valid(q), world.clearance(q).describe()


def test_ur5_home_forearm_and_wrist_2_are_apart_on_the_meshes_and_accepted() -> None:
    q = np.radians([0, -90, 90, -90, -90, 0])
    distances = mesh_pair_distances("ur5", q)
    assert distances[(3, 5)] == pytest.approx(0.0137, abs=0.0005)
    assert arm_only("ur5").is_valid(q)


def test_ur5_cb3_judged_on_a_random_set() -> None:
    """Configurations whose links stand >= 30 mm apart on the meshes (10 mm for the three
    constructional neighbours, :data:`NEIGHBOURS`) are accepted, those
    whose meshes interpenetrate are refused (300 random configurations: the upper arm above
    the base's plane, every other joint anywhere in a turn)."""
    world = arm_only("ur5")
    rng = np.random.default_rng(2024)
    accepted_apart = refused_penetrating = 0
    qs = rng.uniform(-math.pi, math.pi, (300, 6))
    qs[:, 1] = rng.uniform(-math.pi, 0.0, 300)
    for q in qs:
        apart, penetrating = mesh_verdict("ur5", q)
        if penetrating:
            assert not world.is_valid(q), np.degrees(q).round(1)
            refused_penetrating += 1
        elif apart >= 0.030:
            assert world.is_valid(q), (np.degrees(q).round(1), world.clearance(q).describe())
            accepted_apart += 1
    assert accepted_apart >= 20 and refused_penetrating >= 20, (accepted_apart, refused_penetrating)


@cache
def _mesh_bvhs(model: str):
    import coal

    from cellrunner.planning.stl import read_stl

    pmodel, geoms, _ = cb3_meshes(model)
    out = {}
    for g in geoms:
        body = 0 if g.parentJoint == 0 else _body_of(pmodel, g.parentJoint)
        v, t = read_stl(Path(g.meshPath))
        v = v * np.asarray(g.meshScale)
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(t), len(v))
        bvh.addVertices(np.ascontiguousarray(v))
        bvh.addTriangles(np.ascontiguousarray(t, np.int64))
        bvh.endModel()
        out[body] = (g.parentJoint, g.placement.homogeneous, bvh)
    return out


def mesh_pair_distances(model: str, q: np.ndarray) -> dict[tuple[int, int], float]:
    """Distances (m; 0 when touching) between the meshes of non-adjacent links at q, and
    -1 for pairs whose meshes interpenetrate."""
    import coal
    import pinocchio as pin

    pmodel, _, _ = cb3_meshes(model)
    data = pmodel.createData()
    pin.forwardKinematics(pmodel, data, _urdf_q(pmodel, q))
    bvhs = _mesh_bvhs(model)
    placed = {}
    for body, (joint, placement, bvh) in bvhs.items():
        T = data.oMi[joint].homogeneous @ placement
        placed[body] = (coal.Transform3s(T[:3, :3], T[:3, 3]), bvh)
    out = {}
    for a in range(7):
        for b in range(a + 2, 7):
            (ta, ga), (tb, gb) = placed[a], placed[b]
            request = coal.CollisionRequest()
            result = coal.CollisionResult()
            if coal.collide(ga, ta, gb, tb, request, result):
                out[(a, b)] = -1.0
                continue
            out[(a, b)] = coal.distance(
                ga, ta, gb, tb, coal.DistanceRequest(), coal.DistanceResult()
            )
    return out


#: link pairs one joint apart whose meshes sit 13-17 mm apart by construction in most poses
#: (base-upper_arm, forearm-wrist_2, wrist_1-wrist_3): "apart" asks 10 mm of them
NEIGHBOURS = {(0, 2): 0.010, (3, 5): 0.010, (4, 6): 0.010}


def mesh_verdict(model: str, q: np.ndarray, apart_m: float = 0.030) -> tuple[float, bool]:
    """(how far the non-adjacent links' meshes stand apart, scaled so that >= ``apart_m``
    means every pair keeps ``apart_m`` and the constructional neighbours 10 mm; whether any
    interpenetrate)."""
    d = mesh_pair_distances(model, q)
    scaled = [v * apart_m / NEIGHBOURS.get(k, apart_m) for k, v in d.items()]
    return min(scaled), any(v < 0 for v in d.values())
