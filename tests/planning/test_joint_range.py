"""``robot.joint_range`` (SPEC section 11): IK branches, planning (OMPL bounds), the final
verification and ``check`` keep to the cell's narrowed ranges."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.model.trajectory import Trajectory
from cellrunner.planning.collision import CollisionModel
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.timing import MotionLimits
from cellrunner.planning.verify import verify_trajectory
from tests.planning.check_cell import CELL, PICK_PLACE, check

RANGE = [[-120, 120], [-180, 0], [-160, 160], [-270, 90], [-180, 0], [-180, 180]]
TCP = pose_matrix((0, 0, 0.15))


def narrowed_kinematics(model: str = "ur5e") -> ArmKinematics:
    return ArmKinematics(ROBOTS[model].narrowed(RANGE), np.eye(4), TCP)


def test_narrowed_spec_keeps_the_arm_and_reports_it():
    spec = ROBOTS["ur10e"].narrowed(RANGE)
    assert spec.joint_min_deg == tuple(float(lo) for lo, _ in RANGE)
    assert spec.joint_max_deg == tuple(float(hi) for _, hi in RANGE)
    assert spec.d_m == ROBOTS["ur10e"].d_m and spec.rate_hz == 500
    assert spec.joint_range_narrowed and not ROBOTS["ur10e"].joint_range_narrowed
    assert ROBOTS["ur10e"].narrowed(None) is ROBOTS["ur10e"]


def test_ik_branches_lie_inside_the_joint_range():
    """Every branch IK offers lies inside the range, and the range really removes some."""
    full = ArmKinematics(ROBOTS["ur5e"], np.eye(4), TCP)
    kin = narrowed_kinematics()
    lo, hi = np.radians([r[0] for r in RANGE]), np.radians([r[1] for r in RANGE])
    rng = np.random.default_rng(3)
    removed = 0
    for _ in range(60):
        q = rng.uniform(-np.pi, np.pi, 6)
        T = full.T_world_tcp(q)
        near = np.radians([0, -90, 90, -90, -90, 0])
        narrow = kin.ik_all(T, near)
        for s in narrow:
            assert np.all(s >= lo - 1e-9) and np.all(s <= hi + 1e-9)
            assert np.allclose(kin.T_world_tcp(s), T, atol=1e-6)
        removed += len(full.ik_all(T, near)) - len(narrow)
    assert removed > 0


def test_verification_refuses_a_motion_outside_the_joint_range():
    kin = narrowed_kinematics()
    q0 = np.radians([0, -90, 90, -90, -90, 170])
    q1 = np.radians([0, -90, 90, -90, -90, 190])  # wrist 3 beyond +180
    n = 200
    q = q0 + np.linspace(0, 1, n)[:, None] * (q1 - q0)
    trajectory = Trajectory(500.0, np.arange(n) / 500.0, q)
    limits = MotionLimits.from_cell(kin.spec)
    with pytest.raises(InfeasibleError) as error:
        verify_trajectory(
            trajectory,
            step_index=3,
            step_name="move 'x'",
            kinematics=kin,
            limits=limits,
            collision=CollisionModel(kin, [], []),
        )
    message = str(error.value)
    assert message.startswith("step 3 move 'x': joint 6 (wrist_3) at 180.")
    assert "is outside its range [-180, 180] deg (robot.joint_range) at sample" in message


def test_check_plans_inside_the_joint_range_and_saves_it(tmp_path):
    """A pick and place around a wall (a joint move that needs the planner) with narrowed
    base, shoulder, wrist 1, wrist 2 and wrist 3 (the cable case, +-180 deg): every streamed sample lies inside the range."""
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    ranges = "[[-120, 120], [-180, 0], [-160, 160], [-270, 90], [-180, 0], [-180, 180]]"
    cell.write_text(
        CELL.replace(
            "  home: [0, -90, 90, -90, -90, 0]\n",
            f"  home: [0, -90, 90, -90, -90, 0]\n  joint_range: {ranges}\n",
        )
    )
    task = tmp_path / "tasks" / "t.yaml"
    task.write_text(PICK_PLACE)
    plan_file = tmp_path / "plan.json"
    r = check(cell, task, "--save-plan", str(plan_file))
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    plan = json.loads(plan_file.read_text())
    assert plan["joint_range_deg"] == RANGE
    lo, hi = np.array(RANGE, float).T
    for step in plan["steps"]:
        q = np.array(step["samples"])[:, 1:]
        assert np.all(q >= lo - 1e-6) and np.all(q <= hi + 1e-6), step["name"]


def test_check_refuses_a_target_the_joint_range_excludes(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    ranges = "[[-30, 30], [-180, 0], [-160, 160], [-360, 360], [-360, 360], [-360, 360]]"
    cell.write_text(
        CELL.replace(
            "  home: [0, -90, 90, -90, -90, 0]\n",
            f"  home: [0, -90, 90, -90, -90, 0]\n  joint_range: {ranges}\n",
        )
    )
    task = tmp_path / "tasks" / "t.yaml"
    task.write_text(PICK_PLACE)
    r = check(cell, task)
    assert r.returncode == 1, r.stderr[-2000:]
    out = json.loads(r.stdout)
    text = json.dumps(out["errors"])
    assert "is outside its range [-30, 30] (joint_range)" in text
    assert "widen robot.joint_range" in text
