"""Every arm that has no reference cell of its own plans, checks and rehearses a pick and
place scaled to its reach: `check --save-plan` at the arm's controller rate, and the
twin runs it (`dry-run`) for a CB3 and a UR Series arm. Arms without published collision
meshes are refused with the reason."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cellrunner.model.robots import ROBOTS
from tests.rig import cli

#: arms without a reference cell in cells/ (UR7e and UR12e: the UR5e's and UR10e's geometry)
ARMS = ["ur3", "ur10", "ur7e", "ur12e", "ur16e", "ur30"]
#: arms whose collision meshes Universal Robots does not publish: check refuses to guess
NO_MESHES = ["ur15", "ur18", "ur8long"]

TASK = """task: t
steps:
  - move: home
  - pick: {at: a, approach: 0.1, grip: {confirm: closed}}
  - place: {at: b, approach: 0.1}
  - move: home
"""


def write_cell(root: Path, model: str) -> tuple[Path, Path]:
    """A table with a low wall between two spots at half the arm's reach."""
    r = 0.5 * ROBOTS[model].reach_m
    cell = f"""cell: {model}-pick-place
robot:
  model: {model}
  backend: sim
  mount: {{xyz: [0, 0, 0.8], rpy: [0, 0, 180]}}
  home: [0, -90, 90, -90, -90, 0]
  joint_range: [[-180, 180], [-180, 0], [-160, 160], [-270, 90], [-180, 0], [-180, 180]]
tool:
  tcp: {{xyz: [0, 0, 0.15]}}
  payload: {{mass: 0.8, cog: [0, 0, 0.05]}}
  gripper: {{kind: io, close: {{output: close, value: true}}, closed_sensor: closed}}
  geometry: [{{cylinder: {{radius: 0.04, length: 0.09}}, xyz: [0, 0, 0.045]}}]
io:
  outputs: {{close: DO0}}
  inputs: {{closed: DI0}}
fixtures:
  - {{name: table, box: {{size: [{3 * r:.3f}, {3 * r:.3f}, 0.04]}}, pose: {{xyz: [0, 0, 0.78]}}}}
  - {{name: wall, box: {{size: [{0.4 * r:.3f}, 0.02, 0.08]}}, pose: {{xyz: [{r:.3f}, 0, 0.84]}}}}
frames:
  a: {{xyz: [{r:.3f}, {-0.5 * r:.3f}, 0.825], rpy: [180, 0, 0]}}
  b: {{xyz: [{r:.3f}, {0.5 * r:.3f}, 0.825], rpy: [180, 0, 0]}}
parts:
  - {{name: p, box: {{size: [0.04, 0.04, 0.05]}}, mass: 0.2, at: a}}
"""
    (root / "cells").mkdir()
    (root / "tasks").mkdir()
    (root / "cells" / "c.yaml").write_text(cell)
    (root / "tasks" / "t.yaml").write_text(TASK)
    return root / "cells" / "c.yaml", root / "tasks" / "t.yaml"


@pytest.mark.parametrize("model", ARMS)
def test_check_plans_at_the_arms_rate(tmp_path, model):
    cell, task = write_cell(tmp_path, model)
    plan = tmp_path / "plan.json"
    r = cli("check", str(cell), str(task), "--json", "--save-plan", str(plan))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    saved = json.loads(plan.read_text())
    assert saved["model"] == model and saved["rate_hz"] == ROBOTS[model].rate_hz
    assert [s["kind"] for s in json.loads(r.stdout)["steps"]][1:4] == [
        "approach",
        "descend",
        "grip",
    ]


@pytest.mark.parametrize("model", NO_MESHES)
def test_check_refuses_an_arm_without_published_meshes(tmp_path, model):
    cell, task = write_cell(tmp_path, model)
    r = cli("check", str(cell), str(task), "--json")
    assert r.returncode == 1, r.stdout[-3000:] + r.stderr[-2000:]
    (error,) = json.loads(r.stdout)["errors"]
    assert error.startswith(
        f"step 1 move 'home': no collision geometry for robot model '{model}': Universal "
        "Robots publishes no collision meshes for it, and cellrunner does not guess"
    )


@pytest.mark.parametrize("model", ["ur3", "ur30"])
def test_dry_run_places_the_part(tmp_path, model):
    cell, task = write_cell(tmp_path, model)
    r = cli("dry-run", str(cell), str(task), "--json")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    out = json.loads(r.stdout)
    assert (out["result_code"], out["result_text"]) == (0, "OK")
    x, y, _ = out["parts_end_m"]["p"]
    r_m = 0.5 * ROBOTS[model].reach_m
    assert (x, y) == pytest.approx((r_m, 0.5 * r_m), abs=0.005)
