"""The live 3D view's data from the cell model: the scene (links, tool, fixtures), the
link poses by the arm's one kinematics, a job's planned path and the part in the gripper
step by step."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.cli.common import load
from cellrunner.model.arm_geometry import arm_geometry
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld
from cellrunner.web.live_scene import ArmPoses, carried_part, job_of, scene_of, tool_key, world_at
from tests.conftest import ROOT
from tests.rig import CELL, TASK, write_cell


@pytest.fixture(scope="module")
def world_and_task(tmp_path_factory):
    cell_path, task_path = write_cell(tmp_path_factory.mktemp("live"), CELL, TASK)
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(cell_path), str(task_path))
    return CellWorld(cell), task


def test_the_scene_is_the_cell_models(world_and_task):
    world, _ = world_and_task
    scene = scene_of(world)
    json.dumps(scene, allow_nan=False)  # JSON as it is
    assert scene["robot"] == "ur10e" and scene["cell"] == "dryrun-cell"
    names = ["base", "shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"]
    assert [link["name"] for link in scene["links"]] == names
    geometry = arm_geometry("ur10e")
    assert sum(len(link["parts"]) for link in scene["links"]) == len(geometry.parts)
    first = scene["links"][0]["parts"][0]
    assert len(first["vertices"]) == 3 * len(geometry.parts[0].vertices_m)
    assert max(first["faces"]) < len(first["vertices"]) // 3
    (bench,) = scene["fixtures"]
    assert bench["kind"] == "box" and bench["size"] == [1.6, 1.2, 0.05]
    assert bench["T"][3::4][:3] == [0.5, 0.0, 0.775]  # the translation column, row-major
    (tool, *pads) = scene["tool"]
    assert tool["kind"] == "cylinder" and (tool["radius"], tool["length"]) == (0.045, 0.1)
    assert tool["T"][11] == 0.05 and pads  # in the flange frame; the finger pads open
    assert scene["zone"] is None
    assert scene["home_deg"] == pytest.approx([0, -90, 90, -90, -90, 0])


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-3.1, 3.1), min_size=6, max_size=6))
def test_link_poses_are_the_arms_kinematics(world_and_task, q):
    world, _ = world_and_task
    kin = world.kinematics
    poses = ArmPoses(kin).links(np.array(q))
    assert len(poses) == 9
    np.testing.assert_allclose(poses[0], kin.T_world_base)
    np.testing.assert_allclose(poses[7], kin.T_world_flange(np.array(q)), atol=1e-12)
    np.testing.assert_allclose(poses[8], kin.T_world_tcp(np.array(q)), atol=1e-12)
    for T in poses:  # rigid transforms
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
        assert T[3].tolist() == [0, 0, 0, 1]
    # joint i turns link i about its own Z: the link's frame keeps its origin and Z
    moved = np.array(q)
    moved[2] += 0.3
    elbow = ArmPoses(kin).links(moved)[3]
    np.testing.assert_allclose(elbow[:3, 3], poses[3][:3, 3], atol=1e-12)
    np.testing.assert_allclose(elbow[:3, 2], poses[3][:3, 2], atol=1e-12)


def test_a_jobs_path_and_the_part_in_the_gripper_step_by_step(world_and_task):
    world, task = world_and_task
    plan = plan_job(world, task, {}, world.q_home_rad, use_cache=False)
    assert plan.ok
    job = job_of("j1", plan, world)
    json.dumps(job, allow_nan=False)
    assert list(job["tools"]) == [""]  # the cell file's tool all along
    assert job["tools"][""] == scene_of(world)["tool"]
    motions = [s for s in plan.steps if plan.motions.nominal(s) is not None]
    assert [seg["step"] for seg in job["path"]] == [s.index for s in motions]
    for seg, step in zip(job["path"], motions, strict=True):
        q = plan.motions.nominal(step).trajectory.q_rad
        points = np.array(seg["points"]).reshape(-1, 3)
        np.testing.assert_allclose(points[0], plan.motions.tcp_position_m(q[0]), atol=1e-4)
        np.testing.assert_allclose(points[-1], plan.motions.tcp_position_m(q[-1]), atol=1e-4)
    assert set(job["parts"]) == {"can"}
    assert job["parts"]["can"]["kind"] == "cylinder"

    kinds = [s.kind for s in plan.steps]
    grip, release = kinds.index("grip"), kinds.index("release")
    by_step = [carried_part(plan, s.index) for s in plan.steps]
    assert all(p is None for p in by_step[: grip + 1]), by_step  # shown once the grip ended
    assert all(p is not None and p.name == "can" for p in by_step[grip + 1 : release + 1])
    assert all(p is None for p in by_step[release + 1 :])
    assert carried_part(None, 3) is None and carried_part(plan, 0) is None


def test_the_tool_mounted_at_each_step_and_the_path_drawn_with_its_tcp():
    """cnc_tend changes to the finished-part gripper while the machine cuts, and back."""
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(
            str(ROOT / "cells/cnc_tending_ur5e.yaml"), str(ROOT / "tasks/cnc_tend.yaml")
        )
    world = CellWorld(cell)
    plan = plan_job(world, task, {"door_time": 3.0, "cycle_time": 10.0}, world.q_home_rad)
    assert plan.ok, plan.errors
    kinds = [s.kind for s in plan.steps]
    keys = [tool_key(world_at(plan, s.index) or world) for s in plan.steps]
    # the gripper leaves the flange at each unlock and the next one is on it from its lock
    unlock, lock = kinds.index("tool_unlock"), kinds.index("tool_lock")
    unlock2, lock2 = (
        i + lock + 1 for i in (kinds[lock + 1 :].index(k) for k in ("tool_unlock", "tool_lock"))
    )
    assert set(keys[:unlock]) == {""}  # the cell file's tool (raw)
    assert set(keys[unlock:lock]) == {"-@raw"}  # the bare flange, raw's TCP
    assert set(keys[lock:unlock2]) == {"finished"}
    assert set(keys[unlock2:lock2]) == {"-@finished"}
    assert set(keys[lock2:]) == {""}  # raw again
    job = job_of("j2", plan, world)
    assert set(job["tools"]) == {"", "-@raw", "finished", "-@finished"}
    radii = {
        k: [t["radius"] for t in v if t["kind"] == "cylinder"] for k, v in job["tools"].items()
    }
    assert radii["-@raw"] == radii["-@finished"] == []  # nothing on the flange
    assert radii[""] and radii["finished"] and radii[""] != radii["finished"]
    for seg in job["path"]:  # each motion's TCP path with the tool mounted then
        step = next(s for s in plan.steps if s.index == seg["step"])
        q = plan.motions.nominal(step).trajectory.q_rad
        first_point = np.array(seg["points"][:3])
        np.testing.assert_allclose(first_point, plan.motions.tcp_position_m(q[0], step), atol=1e-4)
