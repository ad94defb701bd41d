"""`cellrunner twin` (the virtual UR controller over the cell's MuJoCo twin) and
`cellrunner run --backend ur` (the UR backend through the unmodified ur_rtde client), each
in its own process, over loopback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.rig import (
    CELL,
    DONE,
    TASK,
    TOUR,
    fault_once_moving,
    free_port,
    modbus_client,
    plc_job,
    write_cell,
)


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> tuple[Path, Path]:
    """The rig's small cell and task, laid out once for this module."""
    return write_cell(tmp_path_factory.mktemp("project"), CELL, TASK)


HOST = "127.0.0.23"


@pytest.fixture
def twin(project):
    cell, _ = project
    proc = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.cli.main", "twin", str(cell), "--host", HOST],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    deadline = time.monotonic() + 60
    line = ""
    while time.monotonic() < deadline and "virtual" not in line:
        line = proc.stderr.readline()
        assert line or proc.poll() is None, "the twin exited"
    assert "virtual UR10E controller (e-Series, 500 Hz)" in line
    yield proc
    proc.terminate()
    proc.communicate(timeout=30)


def run_job(project, *extra):
    cell, task = project
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "run",
            str(cell),
            str(task),
            "--backend",
            "ur",
            "--robot-host",
            HOST,
            "--json",
            *extra,
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )


def test_run_through_ur_rtde_on_the_twin(project, twin):
    r = run_job(project)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout)
    assert out["backend"] == "ur" and out["result_code"] == 0
    assert [s["status"] for s in out["steps"]] == ["ok"] * 10
    assert 4.0 < out["cycle_time_s"] < 15.0


def test_protective_stop_on_the_twin_is_recovered(project, twin, tmp_path):
    # two moves (1.8 s): the stop comes in the first; the whole pick and place runs in
    # test_run_through_ur_rtde_on_the_twin
    cell, _ = project
    tour = tmp_path / "tour.yaml"
    tour.write_text(TOUR)
    fault_once_moving(HOST, "protective_stop")  # once the job is under way
    r = run_job((cell, tour))
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout)
    assert out["result_code"] == 0
    assert out["cycle_time_s"] > 6.0  # 1.8 s of moves: the controller's 5 s unlock delay is in it


def test_unreachable_controller_is_exit_3(project):
    r = run_job(project, "--robot-host", "127.0.0.24")
    assert r.returncode == 3, r.stderr[-2000:]
    assert "Traceback" not in r.stderr


def test_serve_with_the_ur_backend_runs_a_plc_job(tmp_path):
    """serve --backend ur against the twin, a job triggered over Modbus TCP."""

    port = free_port("127.0.0.5")
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        CELL + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: 127.0.0.5, port: {port}}}\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    twin = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.cli.main", "twin", str(cell), "--host", HOST],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    serve = None
    try:
        assert "virtual" in twin.stderr.readline()
        serve = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "serve",
                str(cell),
                "--backend",
                "ur",
                "--robot-host",
                HOST,
            ],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        client = modbus_client(port, "127.0.0.5")
        regs = plc_job(client, 9, 1, [], [0])
        assert regs[1] & DONE and (regs[4], regs[5]) == (9, 0), regs
    finally:
        if serve is not None:
            serve.terminate()
            serve.communicate(timeout=60)
        twin.terminate()
        twin.communicate(timeout=30)
    assert serve.returncode == 0


def test_robotiq_gripper_through_its_socket(tmp_path):
    """kind: robotiq: the UR backend drives the gripper through its socket (port 63352 on
    the controller), which the twin serves over its MuJoCo jaws; a grip is confirmed by
    OBJ 2 (object detected), a miss retried and refused."""

    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        CELL.replace(
            "gripper: {kind: io, close: {output: jaws, value: true}, closed_sensor: jaws_closed, "
            "stroke: 0.08, close_time: 0.25}",
            "gripper: {kind: robotiq, stroke: 0.085}",
        )
    )
    task = tmp_path / "tasks" / "t.yaml"
    task.write_text(TASK.replace("grip: {confirm: jaws_closed, ", "grip: {"))
    host = "127.0.0.32"
    twin = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.cli.main", "twin", str(cell), "--host", host],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    try:
        assert "virtual" in twin.stderr.readline()
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "run",
                str(cell),
                str(task),
                "--backend",
                "ur",
                "--robot-host",
                host,
                "--json",
            ],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=300,
        )
        assert r.returncode == 0, r.stderr[-3000:]
        assert json.loads(r.stdout)["result_code"] == 0
    finally:
        twin.terminate()
        twin.communicate(timeout=30)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "dry-run",
            str(cell),
            str(task),
            "--json",
            "--inject",
            "grip_miss@grip",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        env={**os.environ, "MUJOCO_GL": "osmesa"},
    )
    out = json.loads(r.stdout)
    assert (r.returncode, out["result_code"], out["retries"]) == (1, 1, 1)
