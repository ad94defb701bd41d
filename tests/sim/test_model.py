"""The MJCF twin matches the DH model, planning's arm parts and the description."""

from __future__ import annotations

import subprocess
import sys

import mujoco
import numpy as np
import pytest

from cellrunner.model.arm_geometry import available_models
from cellrunner.model.geometry import Box, Mesh, pose_matrix
from cellrunner.model.robots import JOINT_NAMES, ROBOTS
from cellrunner.sim import demo
from cellrunner.sim.description import (
    GripperDescription,
    PartDescription,
    TwinDescription,
    dh_forward,
)
from cellrunner.sim.mjcf import build_mjcf, compile_model
from cellrunner.sim.world import SimWorld


@pytest.mark.parametrize("model_name", available_models())
def test_tcp_site_follows_the_dh_forward_kinematics(model_name: str) -> None:
    desc = demo.demo_description(spec=ROBOTS[model_name], parts=())
    model = compile_model(desc)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    site = model.site("tcp").id
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        for name, value in zip(JOINT_NAMES, q, strict=True):
            data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
        mujoco.mj_kinematics(model, data)
        T = desc.T_world_base @ dh_forward(desc.spec, q) @ desc.T_flange_tcp
        np.testing.assert_allclose(data.site_xpos[site], T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), T[:3, :3], atol=1e-9)


def test_arm_geoms_are_the_planning_parts() -> None:
    from cellrunner.model.arm_geometry import arm_geometry

    desc = demo.demo_description(parts=())
    model = compile_model(desc)
    parts = arm_geometry(desc.spec.name).parts
    for body in range(7):
        expected = [p for p in parts if p.body == body]
        assert expected
        for k, part in enumerate(expected):
            g = model.geom(f"arm{body}_{k}")
            assert g.type[0] == mujoco.mjtGeom.mjGEOM_MESH
            mesh = g.dataid[0]
            start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            local = model.mesh_vert[start : start + count]
            # MuJoCo moves a mesh to its inertial frame: back to the body frame
            R = np.zeros(9)
            mujoco.mju_quat2Mat(R, g.quat)
            in_body = local @ R.reshape(3, 3).T + g.pos
            assert count == len(part.vertices_m)
            np.testing.assert_allclose(
                np.sort(in_body, axis=0), np.sort(part.vertices_m, axis=0), atol=1e-6
            )


def test_fixtures_parts_and_mesh_are_in_the_model(tmp_path) -> None:
    stl = tmp_path / "wedge.stl"
    stl.write_text(_ascii_stl_tetrahedron())
    desc = demo.demo_description(
        fixtures=(
            *demo.demo_description().fixtures,
            demo.Placed("wedge", Mesh(stl, scale=0.1), pose_matrix((0.0, 0.6, 0.9))),
        ),
        parts=(
            PartDescription("a", Box((0.04, 0.04, 0.04)), 0.2, pose_matrix((0.3, 0.1, 0.92))),
            PartDescription("b", Box((0.04, 0.04, 0.04)), 0.5, pose_matrix((0.3, 0.2, 0.92))),
        ),
    )
    model = compile_model(desc)
    assert model.body("part:a").mass[0] == pytest.approx(0.2)
    assert model.body("part:b").mass[0] == pytest.approx(0.5)
    assert model.geom("fixture:wedge").type[0] == mujoco.mjtGeom.mjGEOM_MESH
    np.testing.assert_allclose(model.geom("fixture:table").size, [0.6, 0.4, 0.02])


def test_twin_description_rejects_unknown_gripper_channels() -> None:
    with pytest.raises(
        ValueError, match=r"gripper close output 'DO7' is not an output; known: DO0"
    ):
        demo.demo_description(io_outputs=("DO0",), gripper=GripperDescription(close_output="DO7"))


def test_mjcf_is_plain_xml_with_named_bodies() -> None:
    xml = build_mjcf(demo.demo_description())
    for name in ("base", "link1", "link6", "flange", "tool", "jaw_a", "jaw_b", "part:cube"):
        assert f'name="{name}"' in xml


def test_wrist_reads_zero_at_rest_in_any_pose_payload_compensated() -> None:
    world = SimWorld(demo.demo_description(parts=()))
    world.build()
    for q in ([0, -1.57, 1.57, -1.57, -1.57, 0], [0.7, -1.2, 1.0, 0.3, 1.1, 2.0]):
        world.place_arm(np.array(q, dtype=float))
        for _ in range(200):
            world.step_period()
        wrench = world.measure().wrench_N
        assert np.abs(wrench[:3]).max() < 0.05, wrench
        assert np.abs(wrench[3:]).max() < 0.01, wrench


def test_importing_the_package_does_not_import_mujoco() -> None:
    code = (
        "import sys, cellrunner.backends.sim.backend, cellrunner.sim.render; "
        "print('mujoco' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def _ascii_stl_tetrahedron() -> str:
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    lines = ["solid t"]
    for a, b, c in faces:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {v[i][0]} {v[i][1]} {v[i][2]}" for i in (a, b, c)]
        lines += ["endloop", "endfacet"]
    return "\n".join(lines + ["endsolid t"]) + "\n"


def test_description_field_defaults_are_consistent() -> None:
    desc = TwinDescription(
        spec=ROBOTS["ur10e"],
        T_world_base=np.eye(4),
        T_flange_tcp=pose_matrix((0, 0, 0.2)),
        q_home_rad=(0.0,) * 6,
    )
    assert desc.rate_hz == 500.0
    model = compile_model(desc)
    assert model.opt.timestep == pytest.approx(0.002)


@pytest.mark.parametrize("model_name", ["ur3e", "ur20", "ur30"])
def test_joint_ranges_are_the_cells_joint_range(model_name: str) -> None:
    ranges = [[-170, 170], [-180, 0], [-160, 160], [-270, 90], [-180, 0], [-180, 180]]
    desc = demo.demo_description(spec=ROBOTS[model_name].narrowed(ranges), parts=())
    model = compile_model(desc)
    for name, (lo, hi) in zip(JOINT_NAMES, ranges, strict=True):
        joint = model.joint(name)
        assert joint.limited[0] == 1
        np.testing.assert_allclose(joint.range, np.radians([lo, hi]), atol=1e-6)


def test_a_contact_stop_names_what_touched_the_robots_side_first():
    from cellrunner.sim.contacts import ContactEvent, geom_label

    hit = ContactEvent(1.494, 673.2, ("fixture:infeed_table", "pad:jaw_a"))
    assert hit.describe() == "pad 'jaw_a' met fixture 'infeed_table' at 673 N"
    assert geom_label("fixture:machine:2") == "fixture 'machine'"
    assert geom_label("arm3_0") == "the arm's link 3 (forearm)"
    assert geom_label("part:widget") == "part 'widget'"
    assert geom_label("tool@gripper:1") == "tool 'gripper'"
    assert geom_label("floor") == "the floor"
    assert ContactEvent(0.0, 80.0, ("floor", "arm5_0")).describe() == (
        "the arm's link 5 (wrist 2) met the floor at 80 N"
    )
