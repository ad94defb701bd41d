"""What ``check`` approves for a whole pick and place: every motion step verified and
sealed, in step order, each starting where the motion before it ended, with the gripped
part carried from the grip to the release (and collision-checked as carried)."""

from __future__ import annotations

import contextlib
import io
import itertools

import numpy as np
import pytest

from cellrunner.cli.common import load, parse_params
from cellrunner.model.expand import expand
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.planning import group_timing, task_plan
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT


@pytest.fixture(scope="module")
def plan() -> task_plan.TaskPlan:
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml"))
    world = CellWorld(cell)
    steps = expand(task, cell.cell, parse_params(["slot=2"], task))
    result = task_plan.plan_task(world, steps, world.q_home_rad)
    assert result.ok, result.errors
    return result


def test_every_motion_is_approved_sealed_and_starts_where_the_last_one_ended(plan) -> None:
    motions = [r for r in plan.rows if r.trajectory is not None]
    assert [r.step.kind for r in motions] == [
        "move", "approach", "descend", "lift", "approach", "descend", "retreat", "move",
    ]  # fmt: skip
    approved = [plan.nominal(r.step) for r in motions]
    assert all(a is not None and a.is_sealed for a in approved)
    assert [a.step_index for a in approved] == [r.step.index for r in motions]
    assert [r.status for r in plan.rows] == ["ok"] * len(plan.rows)
    np.testing.assert_array_equal(approved[0].trajectory.q_rad[0], plan.q_start_rad)
    for before, after in itertools.pairwise(approved):
        np.testing.assert_array_equal(before.trajectory.q_rad[-1], after.trajectory.q_rad[0])


def test_a_motion_continues_from_the_one_before_only_when_that_one_moved(plan) -> None:
    """The task's first move goes home from home (no motion): the approach after it starts
    at rest, so the executor streams it as planned instead of planning it again from rest;
    the descend after the approach does run on from it."""
    motions = [r for r in plan.rows if r.trajectory is not None]
    assert len(motions[0].trajectory.q_rad) == 1  # home from home
    assert not plan.continues(motions[1].step)
    assert plan.continues(motions[2].step)  # descend, joined to the approach
    for before, row in itertools.pairwise(motions):
        if plan.continues(row.step):
            assert len(before.trajectory.q_rad) > 1, row.step.label


def test_the_part_is_carried_from_the_grip_to_the_release(plan) -> None:
    kinds = [r.step.kind for r in plan.rows]
    grip, release = kinds.index("grip"), kinds.index("release")
    for i, row in enumerate(plan.rows):
        if row.trajectory is None:
            continue
        carried = grip < i < release
        assert (row.carrying is not None) == carried, (row.step.label, row.carrying)


@pytest.mark.parametrize("model", ["ur3e", "ur3"])
@pytest.mark.parametrize("task_text", ["peg_insert", "probe"])
def test_force_lines_set_off_and_stop_gently(tmp_path, model, task_text) -> None:
    """A force step's line accelerates at most ``FORCE_TCP_ACCEL_MPS2`` at the TCP, as
    moveUntilContact does: the tool's mass pushes on the wrist sensor in proportion (the
    peg line set off at ~5 m/s^2: 2.2 N through ur_rtde, a contact to a 1.5 N probe)."""
    from tests.cells.reference import probe_task

    text = (ROOT / "cells/peg_ur3e.yaml").read_text().replace("model: ur3e", f"model: {model}")
    (tmp_path / "cell.yaml").write_text(text)
    (tmp_path / "probe.yaml").write_text(probe_task(0.1))
    task_path = (
        str(ROOT / "tasks/peg_insert.yaml")
        if task_text == "peg_insert"
        else tmp_path / "probe.yaml"
    )
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(tmp_path / "cell.yaml"), str(task_path))
    world = CellWorld(cell)
    result = task_plan.plan_task(world, expand(task, cell.cell, {}), world.q_home_rad)
    assert result.ok, result.errors
    forces = [r for r in result.rows if r.step.kind in ("insert", "move_until_contact")]
    assert forces
    for row in forces:
        p = world.kinematics.p_world_tcp_many(row.trajectory.q_rad)
        p = np.vstack([p[:1], p, p[-1:]])  # from rest, to rest
        accel = np.linalg.norm(np.diff(p, 2, axis=0), axis=1) * row.trajectory.rate_hz**2
        assert accel.max() <= task_plan.FORCE_TCP_ACCEL_MPS2 * 1.05, (row.step.label, accel.max())
        assert accel.max() > 0.2 * task_plan.FORCE_TCP_ACCEL_MPS2  # it does accelerate


SWING = "task: swing\nsteps:\n  - move: home\n  - move: [90, -90, 90, -90, -90, 0]\n"


def _pin_between_samples(tmp_path):
    """The demo cell with a 2 mm pin where the tool's rim passes 3 mm deep halfway between
    two of the planner's samples of the joint move of ``SWING`` (the base turning 90 deg),
    and that task: sampling the move every 0.1 rad sees nothing, a proof of it hits the pin."""
    from tests.planning.pins import pin_between_samples

    with contextlib.redirect_stderr(io.StringIO()):
        cell, _ = load(str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/home.yaml"))
    kin = CellWorld(cell).kinematics
    a, b = np.radians([0, -90, 90, -90, -90, 0]), np.radians([90, -90, 90, -90, -90, 0])
    x, y, z = pin_between_samples(kin, a, b, 0.045, 0.04)  # the demo tool's cylinder
    text = (ROOT / "cells/demo_ur5e.yaml").read_text()
    text = text.replace(
        "fixtures:\n",
        f"fixtures:\n  - {{name: pin, box: {{size: [0.002, 0.002, 0.002]}}, pose: {{xyz: [{x:.6f}, {y:.6f}, {z:.6f}]}}}}\n",
    )
    (tmp_path / "cell.yaml").write_text(text)
    (tmp_path / "swing.yaml").write_text(SWING)
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(tmp_path / "cell.yaml"), str(tmp_path / "swing.yaml"))
    world = CellWorld(cell)
    return world, expand(task, cell.cell, {}), a, b


def test_a_joint_move_sampling_missed_is_planned_again_proven(tmp_path, monkeypatch) -> None:
    """The planner only samples a task's joint moves; the verifier proves the timed
    trajectory, and a move whose proof fails is planned again with every piece proven."""
    from cellrunner.planning import joint_path

    world, steps, a, b = _pin_between_samples(tmp_path)
    assert joint_path.sampled_free(world.collision, a, b)
    assert not world.collision.check_motion(a, b).ok

    proven_calls = []
    original = joint_path.plan_joint_path

    def spy(*args, **kwargs):
        proven_calls.append(kwargs.get("proven", True))
        return original(*args, **kwargs)

    monkeypatch.setattr(joint_path, "plan_joint_path", spy)
    result = task_plan.plan_task(world, steps, world.q_home_rad)
    assert result.ok, result.errors
    assert proven_calls == [False, False, True]  # home (no move), the swing, the swing again
    q = result.rows[1].trajectory.q_rad
    assert world.collision.check_path(q).ok
    u = (b - a) / np.linalg.norm(b - a)
    off_line = (q - a) - np.outer((q - a) @ u, u)
    assert np.linalg.norm(off_line, axis=1).max() > 0.01  # round the pin, not straight

    # the world remembers the move as proven: planned again, the swing is not sampled
    proven_calls.clear()
    assert task_plan.plan_task(world, steps, world.q_home_rad).ok
    assert proven_calls == []

    # without the proven plan, the verifier refuses the sampled move by the pin's name (in a
    # fresh world, which remembers no move)
    monkeypatch.setattr(group_timing, "_prove_sampled", lambda motion: False)
    fresh = CellWorld(world.loaded)
    refused = task_plan.plan_task(fresh, steps, fresh.q_home_rad)
    assert not refused.ok
    assert refused.errors[0].startswith("step 2 move") and "'pin'" in refused.errors[0]


@pytest.mark.parametrize("cell", ["bin_to_shelf_ur5", "bin_to_shelf_ur10e"])
def test_a_wrist_at_the_edge_of_its_range_still_blends(cell) -> None:
    """At shelf slot 3 the wrist stands at -180 deg, the edge of the cell's narrowed range,
    along the descend. The timing spline overshot it by ~1e-5 rad where the approach's
    blend arc joins the line, so the blended group failed verification and every such
    slot stopped between approach and descend (0.4-0.6 s a cycle)."""
    with contextlib.redirect_stderr(io.StringIO()):
        loaded, task = load(str(ROOT / f"cells/{cell}.yaml"), str(ROOT / f"tasks/{cell}.yaml"))
    world = CellWorld(loaded)
    steps = expand(task, loaded.cell, parse_params(["slot=3"], task))
    result = task_plan.plan_task(world, steps, world.q_home_rad)
    assert result.ok, result.errors
    kin = world.kinematics
    descend = next(r for r in result.rows if r.step.kind == "descend" and "shelf" in r.step.label)
    # a place's descend sets its part down from rest, gently (issue 33); the edge of the
    # wrist's range still holds along it and along the approach's blends elsewhere
    assert not result.continues(descend.step)
    q = descend.trajectory.q_rad
    assert np.isclose(q[:, 5].min(), kin.q_min_rad[5], atol=1e-6)  # along the edge
    for row in result.rows:
        if row.trajectory is not None:
            assert (row.trajectory.q_rad >= kin.q_min_rad).all(), row.step.label
            assert (row.trajectory.q_rad <= kin.q_max_rad).all(), row.step.label


def test_a_move_planned_again_that_finds_no_path_is_named_itself(tmp_path, monkeypatch) -> None:
    """The proven plan of a sampled move comes when its group is timed, after later steps
    were planned; when it fails, the row and the error are that move's, not the last
    step's."""
    from cellrunner.errors import InfeasibleError
    from cellrunner.planning import joint_path

    world, _, _, _ = _pin_between_samples(tmp_path)
    (tmp_path / "swing_back.yaml").write_text(SWING + "  - move: home\n")
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(tmp_path / "cell.yaml"), str(tmp_path / "swing_back.yaml"))
    original = joint_path.plan_joint_path

    def no_proven_path(*args, **kwargs):
        if kwargs.get("proven", True):
            raise InfeasibleError(
                Failure(FailureKind.COLLISION, "no collision-free joint path found within 2.0 s")
            )
        return original(*args, **kwargs)

    monkeypatch.setattr(joint_path, "plan_joint_path", no_proven_path)
    result = task_plan.plan_task(world, expand(task, cell.cell, {}), world.q_home_rad)
    assert not result.ok
    assert len(result.errors) == 1 and result.errors[0].startswith("step 2 "), result.errors
    assert result.errors[0].endswith(": no collision-free joint path found within 2.0 s")
    # the group was not timed: its first move is unplanned too
    assert [r.status for r in result.rows] == ["not planned", "failed", "not planned"]
