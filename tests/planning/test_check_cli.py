"""`cellrunner check` as a user runs it, on cells and tasks written here."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import ur_analytic_ik

from cellrunner.model import geometry
from cellrunner.model.robots import ROBOTS
from tests.conftest import ROOT
from tests.planning.check_cell import CELL, PICK_PLACE, check


def project(tmp_path: Path, task: str) -> tuple[Path, Path]:
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(CELL)
    task_path = tmp_path / "tasks" / "t.yaml"
    task_path.write_text(task)
    return cell, task_path


def test_feasible_task_and_saved_plan_pass_an_independent_check(tmp_path):
    cell, task = project(tmp_path, PICK_PLACE)
    plan_file = tmp_path / "plan.json"
    r = check(cell, task, "--save-plan", str(plan_file))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["ok"] and out["errors"] == [] and out["cycle_time_s"] > 0
    assert [s["kind"] for s in out["steps"]] == [
        "move",
        "approach",
        "descend",
        "grip",
        "lift",
        "approach",
        "descend",
        "release",
        "retreat",
        "move",
    ]
    assert {"index", "name", "kind", "duration_s", "status", "message", "attempts"} <= set(
        out["steps"][0]
    )
    plan = json.loads(plan_file.read_text())
    assert plan["model"] == "ur5e" and plan["rate_hz"] == 500 and len(plan["joint_names"]) == 6
    _independent_check(plan, speed_deg_s=100 * 0.9, accel_deg_s2=250 * 0.9, tcp_mps=0.8 * 0.9)


def _independent_check(plan: dict, speed_deg_s: float, accel_deg_s2: float, tcp_mps: float) -> None:
    """Limits, continuity and straightness from the saved samples alone, with
    ur-analytic-ik's FK (not the planner's pinocchio model). The steps are checked as the
    engine streams them: one stream, a step's first sample dropped when it repeats the
    set-point before it (a non-stop join or a start from rest), at rest at both ends."""
    spec = ROBOTS[plan["model"]]
    T_world_base = geometry.pose_matrix(plan["mount"]["xyz"], plan["mount"]["rpy"])
    T_flange_tcp = geometry.pose_matrix(plan["tcp"]["xyz"], plan["tcp"]["rpy"])
    fk = getattr(ur_analytic_ik, spec.name).forward_kinematics

    def tcp(q_deg):
        return (T_world_base @ fk(*np.radians(q_deg)) @ T_flange_tcp)[:3, 3]

    dt = 1.0 / plan["rate_hz"]
    stream = []
    for step in plan["steps"]:
        s = np.array(step["samples"])
        t, q = s[:, 0], s[:, 1:]
        np.testing.assert_allclose(np.diff(t), dt, atol=1e-9)
        assert np.all(np.abs(q) <= 360)
        if stream:
            assert np.abs(q[0] - stream[-1]).max() <= speed_deg_s * dt * 1.001 + 1e-9  # continuous
            if np.array_equal(q[0], stream[-1]):
                q = q[1:]
        if step["kind"] in ("descend", "lift", "retreat", "linear"):
            p = np.array([tcp(x) for x in s[:, 1:]])
            a0, b0 = p[0], p[-1]
            d = b0 - a0
            u = np.clip((p - a0) @ d / (d @ d), 0, 1)
            off = np.linalg.norm(p - (a0 + u[:, None] * d), axis=1)
            assert off.max() <= 0.001, (step["index"], off.max())
        stream.extend(q)
    q = np.array(stream)
    padded = np.vstack([q[:1], q, q[-1:]])
    v = np.diff(padded, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    assert np.abs(v).max() <= speed_deg_s * 1.001, np.abs(v).max()
    assert np.abs(a).max() <= accel_deg_s2 * 1.01 + 1.0, np.abs(a).max()
    p = np.array([tcp(x) for x in q])
    assert (np.linalg.norm(np.diff(p, axis=0), axis=1) / dt).max() <= tcp_mps * 1.001


def test_out_of_reach_is_refused_naming_the_step(tmp_path):
    cell, task = project(
        tmp_path, "task: t\nsteps:\n  - move: home\n  - approach: {to: far_away, distance: 0.1}\n"
    )
    r = check(cell, task)
    assert r.returncode == 1
    out = json.loads(r.stdout)
    assert not out["ok"]
    assert out["errors"][0].startswith("step 2 approach 'far_away': out of reach (")
    assert "UR5e reach 0.85 m" in out["errors"][0]
    assert out["steps"][1]["status"] == "failed"


def test_line_through_a_fixture_is_refused(tmp_path):
    task = "task: t\nsteps:\n  - move: home\n  - approach: {to: over_block, distance: 0.15}\n  - descend: {to: over_block}\n"
    cell, task_path = project(tmp_path, task)
    r = check(cell, task_path)
    assert r.returncode == 1
    error = json.loads(r.stdout)["errors"][0]
    assert error.startswith("step 3 descend 'over_block': tool 'gripper' "), error
    assert "fixture 'block'" in error and "along the line" in error


def test_every_pattern_slot_is_checked(tmp_path):
    task = """task: t
params:
  slot: {type: int, min: 0, max: 5, default: 0}
steps:
  - move: home
  - approach: {to: a, distance: 0.1}
  - place: {at: grid, approach: 0.1, pattern: {grid: [2, 3], pitch: [0.05, 0.5], index: slot}}
"""
    cell, task_path = project(tmp_path, task)
    r = check(cell, task_path)
    assert r.returncode == 1, r.stdout
    out = json.loads(r.stdout)
    assert out["steps"][2]["status"] == "ok"  # slot 0 itself is fine
    assert out["slots_checked"] == {"slot": [0, 1, 2, 3, 4, 5]}
    assert any(e.startswith("slot=2: step") for e in out["errors"]), out["errors"]


def test_bad_param_is_exit_2(tmp_path):
    cell, task = project(tmp_path, PICK_PLACE)
    r = check(cell, task, "-p", "slot=1")
    assert r.returncode == 2
    assert r.stderr.strip().endswith("cellrunner check: error: unknown param 'slot'; known: (none)")


def test_cache_hits_and_misses(tmp_path):
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.job_plan import plan_key
    from cellrunner.planning.world import CellWorld

    cell, task = project(tmp_path, PICK_PLACE)
    first = check(cell, task)
    second = check(cell, task)
    assert json.loads(first.stdout)["steps"] == json.loads(second.stdout)["steps"]
    assert len(list((tmp_path / "var" / "plan-cache").glob("*.npz"))) == 1
    loaded = load_cell(cell)
    world = CellWorld(loaded)
    key = plan_key(world, load_task(task, loaded), {}, world.q_home_rad)
    cell.write_text(CELL.replace("margin: 0.9", "margin: 0.85"))
    loaded2 = load_cell(cell)
    world2 = CellWorld(loaded2)
    assert plan_key(world2, load_task(task, loaded2), {}, world2.q_home_rad) != key
    assert plan_key(world, load_task(task, loaded), {}, world.q_home_rad + 1e-3) != key
    # the key is made of the digests taken on loading: no file is read to make it
    cell.unlink()
    assert plan_key(world, load_task(task, loaded), {}, world.q_home_rad) == key


def test_cached_plan_is_verified_before_use(tmp_path):
    from cellrunner.errors import InfeasibleError
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.job_plan import plan_job
    from cellrunner.planning.world import CellWorld

    cell, task = project(tmp_path, PICK_PLACE)
    assert check(cell, task).returncode == 0
    npz = next((tmp_path / "var" / "plan-cache").glob("*.npz"))
    data = dict(np.load(npz))
    offset, shape = json.loads(bytes(data["meta"]).decode())["arrays"]["q2"]
    q2 = data["blob"][offset : offset + shape[0] * shape[1]].reshape(shape)
    q2 += np.radians(5) * np.linspace(0, 1, shape[0])[:, None]  # tampered, in the blob
    np.savez(npz, **data)
    loaded = load_cell(cell)
    world = CellWorld(loaded)
    plan = plan_job(world, load_task(task, loaded), {}, world.q_home_rad).task_plan
    with pytest.raises(InfeasibleError):
        plan.nominal(plan.rows[2].step)


def test_memory_cache_keeps_the_most_recently_used_plans(monkeypatch):
    """serve's in-memory plans are bounded; a plan is kept from its second use on, so
    one-off plans (a job starting where a fault left the arm) never take the place of the
    plans in use, and of those the least recently used goes first."""
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.job_plan import plan_job, plan_key
    from cellrunner.planning.world import CellWorld

    loaded = load_cell(ROOT / "cells" / "demo_ur5e.yaml")
    task = load_task(ROOT / "tasks" / "pick_place.yaml", loaded)
    world = CellWorld(loaded)
    store = world.plans
    monkeypatch.setattr(store, "MEMORY_MAX", 2)
    home = world.q_home_rad
    key = {s: plan_key(world, task, {"slot": s}, home) for s in range(4)}
    for s in (0, 1):
        plan_job(world, task, {"slot": s}, home)
    assert not store.memory  # asked for once: not kept
    plans = {s: plan_job(world, task, {"slot": s}, home).task_plan for s in (0, 1)}
    assert set(store.memory) == {key[0], key[1]}  # asked for again: kept
    assert plan_job(world, task, {"slot": 0}, home).task_plan is plans[0]  # from memory
    one_off = home + np.radians([0, 0, 0, 0, 0, 10])
    assert plan_job(world, task, {"slot": 3}, one_off).ok
    assert set(store.memory) == {key[0], key[1]}  # a one-off plan takes no place
    for _ in range(2):
        plan_job(world, task, {"slot": 2}, home)
    assert set(store.memory) == {key[0], key[2]}  # slot 1 was the least recently used
