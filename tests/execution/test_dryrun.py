"""`cellrunner dry-run` end to end in the MuJoCo twin: the normal job and each fault,
detected through sensors (the twin makes the fault physically happen)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

CELL = """
cell: dryrun-cell
robot:
  model: ur10e
  backend: sim
  mount: {xyz: [0, 0, 0.8], rpy: [0, 0, 180]}
  home: [0, -90, 90, -90, -90, 0]
  limits: {joint_speed: 110, joint_accel: 400, tcp_speed: 1.2, margin: 0.9}
tool:
  tcp: {xyz: [0, 0, 0.17]}
  payload: {mass: 1.5, cog: [0, 0, 0.06]}
  gripper: {kind: io, close: {output: jaws, value: true}, closed_sensor: jaws_closed, stroke: 0.08, close_time: 0.25}
  geometry: [{cylinder: {radius: 0.045, length: 0.1}, xyz: [0, 0, 0.05]}]
io:
  outputs: {jaws: TO0}
  inputs: {jaws_closed: TI0}
fixtures:
  - {name: bench, box: {size: [1.6, 1.2, 0.05]}, pose: {xyz: [0.5, 0, 0.775]}}
frames:
  pick: {xyz: [0.7, -0.4, 0.83], rpy: [180, 0, 45]}
  drop: {xyz: [0.7, 0.4, 0.835], rpy: [180, 0, 0]}
parts:
  - {name: can, cylinder: {radius: 0.025, length: 0.06}, mass: 0.4, at: pick}
"""

TASK = """
task: move_can
steps:
  - move: home
  - pick:
      at: pick
      approach: 0.12
      grip: {confirm: jaws_closed, force: {min: 2.5, max: 30}, timeout: 1.0}
      retry: {attempts: 2, between: [release, {retreat: 0.04}]}
  - place: {at: drop, approach: 0.12}
  - move: home
on_protective_stop: {resume: true, max: 1}
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("dryrun")
    (root / "cells").mkdir()
    (root / "tasks").mkdir()
    (root / "cells" / "c.yaml").write_text(CELL)
    (root / "tasks" / "t.yaml").write_text(TASK)
    return root / "cells" / "c.yaml", root / "tasks" / "t.yaml"


def dry_run(project, *extra) -> tuple[int, dict]:
    cell, task = project
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "dry-run",
            str(cell),
            str(task),
            "--json",
            *extra,
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    assert "Traceback" not in r.stderr, r.stderr
    return r.returncode, json.loads(r.stdout)


def statuses(out):
    return {s["index"]: (s["kind"], s["status"], s["attempts"]) for s in out["steps"]}


def test_normal_job_completes_and_tracks_the_plan(project):
    code, out = dry_run(project)
    assert code == 0 and out["ok"] and out["result_code"] == 0, out
    assert all(s["status"] == "ok" for s in out["steps"])
    assert out["max_tracking_error_m"] < 0.005
    planned, simulated = out["planned_cycle_time_s"], out["cycle_time_s"]
    assert abs(simulated - planned) / planned < 0.05, (planned, simulated)
    assert {
        "ok",
        "cell",
        "task",
        "params",
        "cycle_time_s",
        "steps",
        "errors",
        "planned_cycle_time_s",
        "max_tracking_error_m",
        "result_code",
    } <= set(out)


def test_grip_miss_ends_with_no_part_after_the_attempts(project):
    code, out = dry_run(project, "--inject", "grip_miss@grip")
    assert (code, out["result_code"]) == (1, 1)
    assert statuses(out)[4] == ("grip", "failed", 2)
    assert out["retries"] == 1
    assert "jaws_closed not true within 1 s" in out["steps"][3]["message"]


def test_part_slip_in_transit_is_part_lost(project):
    code, out = dry_run(project, "--inject", "part_slip@approach#2")
    assert (code, out["result_code"]) == (1, 2)
    assert statuses(out)[6][1] == "failed"


def test_protective_stop_is_held_then_resumed_after_5s(project):
    _, normal = dry_run(project)
    code, out = dry_run(project, "--inject", "protective_stop@approach#2")
    assert (code, out["result_code"]) == (0, 0), out
    assert all(s["status"] == "ok" for s in out["steps"])
    assert out["cycle_time_s"] >= normal["cycle_time_s"] + 5.0  # the controller's unlock delay
    assert out["max_tracking_error_m"] < 0.005


def test_second_protective_stop_beyond_max_is_100(project):
    code, out = dry_run(
        project, "--inject", "protective_stop@approach#1", "--inject", "protective_stop@approach#2"
    )
    assert (code, out["result_code"]) == (1, 100)


def test_estop_aborts_with_101(project):
    code, out = dry_run(project, "--inject", "estop@move#2")
    assert (code, out["result_code"]) == (1, 101)
    assert statuses(out)[10][1] == "failed"


def test_robot_disconnect_is_102(project):
    code, out = dry_run(project, "--inject", "robot_disconnect@lift")
    assert (code, out["result_code"]) == (1, 102)


def test_bad_injection_is_exit_2(project):
    cell, task = project
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "dry-run",
            str(cell),
            str(task),
            "--inject",
            "grip_mis@grip",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert r.returncode == 2
    assert "unknown fault 'grip_mis'; known: grip_miss, part_slip" in r.stderr


def test_report_has_pictures_and_plots(project, tmp_path):
    code, _out = dry_run(project, "--report", str(tmp_path / "rep"))
    assert code == 0
    files = {p.name for p in (tmp_path / "rep").iterdir()}
    assert {"result.json", "joints.png", "tcp_path.png", "end.png"} <= files
    assert any(name.startswith("step") and name.endswith("_grip.png") for name in files)
    assert (tmp_path / "rep" / "end.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "rep" / "result.json").read_text())["result_code"] == 0


def test_json_logs_are_bound_with_cell_job_step_attempt(project):
    cell, task = project
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "--log-format",
            "json",
            "dry-run",
            str(cell),
            str(task),
            "--inject",
            "grip_miss@grip",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    events = [json.loads(line) for line in r.stderr.splitlines() if line.startswith("{")]
    steps = [e for e in events if e["event"] == "step"]
    assert steps and all(
        {"cell", "job_id", "step", "attempt", "timestamp"} <= set(e) for e in steps
    )
    assert {e["cell"] for e in events} == {"dryrun-cell"}
    assert max(e["attempt"] for e in steps if e["step"] == 4) == 2  # the grip's retry
    assert any(e["event"] == "retry" for e in events)
    assert events[-1]["event"] == "job_end" and events[-1]["result_code"] == 1
