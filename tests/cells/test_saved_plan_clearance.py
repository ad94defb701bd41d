"""An independent check of saved plans: `check --save-plan` on a reference cell, then every
saved sample is posed on the arm's real geometry, never on our CollisionModel or our parts.

- UR5 (CB3): Universal Robots' collision meshes from example-robot-data, posed by the URDF's
  own chain (pinocchio, the URDF's ``base`` frame is the controller's base), distances by
  coal: every moving link's mesh against every fixture, and every two links that are not
  neighbours.
- UR10e: the surface points sampled on UR's meshes (``tests/data/arm_surface_points``,
  written by ``scripts/derive_arm_collision.py``), posed by our forward kinematics, against
  the fixtures' boxes (exact signed distance).

Every sample of every slot must keep a positive clearance. The base does not move and stands
on a fixture (its CB3 mesh reaches 3 mm below the mounting face): it is not checked against
fixtures, as in ``check``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ruamel.yaml import YAML
from scipy.spatial.transform import Rotation

from tests.conftest import ROOT

ENV = {**os.environ, "OMP_NUM_THREADS": "1"}
POINTS = ROOT / "tests" / "data" / "arm_surface_points"
URDF_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")


def rpy_deg_matrix(xyz: list[float], rpy_deg: list[float]) -> np.ndarray:
    """SPEC pose: translation, rotation XYZ fixed-axis (Rz(yaw) Ry(pitch) Rx(roll)), deg;
    built with scipy rather than cellrunner's own pose code, to stay independent."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_matrix()
    T[:3, 3] = xyz
    return T


def fixture_boxes(cell: dict[str, Any]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, T_world_box, half sizes) of the cell's fixtures, read from the YAML itself."""
    out = []
    for f in cell["fixtures"]:
        assert set(f) <= {"name", "box", "pose"}, f"this check knows boxes only: {f}"
        pose = f.get("pose", {})
        T = rpy_deg_matrix(pose.get("xyz", [0, 0, 0]), pose.get("rpy", [0, 0, 0]))
        out.append((f["name"], T, 0.5 * np.asarray(f["box"]["size"], float)))
    return out


def saved_plan(tmp_path: Path, cell: str, task: str, slot: int) -> tuple[dict, dict]:
    plan_path = tmp_path / f"plan{slot}.json"
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "check", cell, task, "-p", f"slot={slot}"]
        + ["--save-plan", str(plan_path)],
        cwd=ROOT,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    plan = json.loads(plan_path.read_text())
    cell_doc = YAML(typ="safe").load((ROOT / cell).read_text())
    assert plan["model"] == cell_doc["robot"]["model"]
    assert sum(len(s["samples"]) for s in plan["steps"]) > 100
    return plan, cell_doc


def samples_rad(plan: dict) -> list[tuple[str, np.ndarray]]:
    return [
        (f"step {s['index']} {s['kind']}", np.radians(np.asarray(s["samples"])[:, 1:]))
        for s in plan["steps"]
    ]


def cb3_urdf(model: str) -> Path:
    """The CB3 URDF installed with example-robot-data (its meshes beside it)."""
    from importlib import metadata

    dist = metadata.distribution("example-robot-data")
    return next(
        Path(str(dist.locate_file(f)))
        for f in dist.files or ()
        if str(f).endswith(f"ur_description/urdf/{model}_robot.urdf")
    )


def mount(plan: dict) -> np.ndarray:
    return rpy_deg_matrix(plan["mount"]["xyz"], plan["mount"]["rpy"])


@pytest.mark.parametrize("slot", range(6))
def test_ur5_plan_clears_the_fixtures_on_the_real_cb3_meshes(tmp_path, slot):
    import coal
    import pinocchio as pin

    plan, cell = saved_plan(
        tmp_path, "cells/bin_to_shelf_ur5.yaml", "tasks/bin_to_shelf_ur5.yaml", slot
    )
    urdf_path = cb3_urdf("ur5")
    urdf = str(urdf_path)
    model = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION, str(urdf_path.parents[4]))
    data, gdata = model.createData(), pin.GeometryData(geom)
    meshes = [(k, g) for k, g in enumerate(geom.geometryObjects) if g.meshPath.endswith(".stl")]
    assert len(meshes) == 7
    link_of = {k: g.parentJoint for k, g in meshes}  # pinocchio joint: 0 base .. 6 wrist 3
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    T_world_urdf = mount(plan) @ np.linalg.inv(data.oMf[model.getFrameId("base")].homogeneous)
    idx = [model.joints[model.getJointId(f"{j}_joint")].idx_q for j in URDF_JOINTS]
    boxes = [(name, coal.Box(*(2 * h)), _coal_tf(T)) for name, T, h in fixture_boxes(cell)]
    request = coal.DistanceRequest()
    spheres = {}  # bounding spheres (centre in the geometry frame, radius): a cheap proof
    for k, g in meshes:
        g.geometry.computeLocalAABB()
        spheres[k] = (np.asarray(g.geometry.aabb_center), float(g.geometry.aabb_radius))
    box_frames = [(T, h) for _, T, h in fixture_boxes(cell)]
    pairs = [(k, ("box", b)) for k, _ in meshes if link_of[k] for b in range(len(boxes))]
    pairs += [
        (k, ("link", k2))
        for k, _ in meshes
        for k2, _ in meshes
        if k2 > k and abs(link_of[k2] - link_of[k]) >= 2
    ]
    geometry = dict(meshes)
    worst = (math.inf, "")
    computed = 0
    for label, qs in samples_rad(plan):
        for q in qs:
            qu = pin.neutral(model)
            qu[idx] = q
            pin.updateGeometryPlacements(model, data, geom, gdata, qu)
            T = {k: T_world_urdf @ gdata.oMg[k].homogeneous for k, _ in meshes}
            centre = {k: T[k][:3, :3] @ spheres[k][0] + T[k][:3, 3] for k in T}
            for k, (kind, j) in pairs:
                if kind == "box":  # the mesh's bounding sphere clears the box: so does the mesh
                    if box_signed_distance(centre[k][None], *box_frames[j])[0] > spheres[k][1]:
                        continue
                    other, T_other, name = boxes[j][1], boxes[j][2], boxes[j][0]
                else:
                    if np.linalg.norm(centre[k] - centre[j]) > spheres[k][1] + spheres[j][1]:
                        continue  # the bounding spheres are apart: positive clearance
                    other, T_other, name = geometry[j].geometry, _coal_tf(T[j]), geometry[j].name
                computed += 1
                d = coal.distance(
                    geometry[k].geometry,
                    _coal_tf(T[k]),
                    other,
                    T_other,
                    request,
                    coal.DistanceResult(),
                )
                worst = min(worst, (d, f"{label}: {geometry[k].name} - {name}"))
    assert computed > 0  # the arm does come near the fixtures
    assert worst[0] > 0.0, worst


@pytest.mark.parametrize("slot", [0, 8])
def test_ur10e_plan_clears_the_fixtures_on_the_sampled_mesh_surface(tmp_path, slot):
    from cellrunner.model.robots import ROBOTS
    from cellrunner.planning.kinematics import ArmKinematics

    plan, cell = saved_plan(
        tmp_path, "cells/bin_to_shelf_ur10e.yaml", "tasks/bin_to_shelf_ur10e.yaml", slot
    )
    stored = np.load(POINTS / "ur10e.npz")
    links = ("base", "shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
    points = [stored[name].astype(float) for name in links]  # in our joint frames
    kin = ArmKinematics(ROBOTS["ur10e"], np.eye(4), np.eye(4))
    data = kin.model.createData()
    T_world_base = mount(plan)
    boxes = fixture_boxes(cell)
    import pinocchio as pin

    # each link's points in slabs along its longest axis, each slab in a bounding sphere: a
    # slab whose sphere clears a box clears it (the box's distance from the centre less the
    # radius is a lower bound); only the others are measured point by point
    slabs = [_slabs(p, 8) for p in points]
    worst = (math.inf, "")
    computed = 0
    for label, qs in samples_rad(plan):
        frames = np.empty((len(qs), 7, 4, 4))  # world frame of every body at every sample
        for i, q in enumerate(qs):
            pin.forwardKinematics(kin.model, data, q)
            frames[i] = [T_world_base @ data.oMi[body].homogeneous for body in range(7)]
        for body in range(1, 7):
            R, t = frames[:, body, :3, :3], frames[:, body, :3, 3]
            for pts, centre, radius in slabs[body]:
                centres = R @ centre + t
                for name, T_box, half in boxes:
                    near = np.flatnonzero(box_signed_distance(centres, T_box, half) <= radius)
                    for chunk in (
                        np.array_split(near, math.ceil(len(near) / 256)) if len(near) else []
                    ):
                        world = pts @ R[chunk].transpose(0, 2, 1) + t[chunk, None]
                        d = box_signed_distance(world.reshape(-1, 3), T_box, half)
                        computed += len(chunk)
                        worst = min(worst, (float(d.min()), f"{label}: {links[body]} - {name}"))
    assert computed > 0  # the arm does come near the fixtures
    assert worst[0] > 0.0, worst


def _slabs(points: np.ndarray, n: int) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """``points`` cut into ``n`` slabs along their longest axis: (points, centre, radius)."""
    axis = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][0]
    order = np.argsort(points @ axis)
    out = []
    for part in np.array_split(points[order], n):
        centre = 0.5 * (part.min(axis=0) + part.max(axis=0))
        out.append((part, centre, float(np.linalg.norm(part - centre, axis=1).max())))
    return out


def box_signed_distance(
    points: np.ndarray, T_world_box: np.ndarray, half: np.ndarray
) -> np.ndarray:
    """Signed distance (m) of world points to a box (negative inside)."""
    local = (points - T_world_box[:3, 3]) @ T_world_box[:3, :3]
    q = np.abs(local) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0.0)


def _coal_tf(T: np.ndarray) -> Any:
    import coal

    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3]))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3]))
    return tf
