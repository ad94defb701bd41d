"""`cellrunner dry-run` end to end in the MuJoCo twin: the normal job and each fault,
detected through sensors (the twin makes the fault physically happen)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.rig import CELL, TASK, cli, cli_json, write_cell


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> tuple[Path, Path]:
    return write_cell(tmp_path_factory.mktemp("dryrun"), CELL, TASK)


def statuses(out):
    return {s["index"]: (s["kind"], s["status"], s["attempts"]) for s in out["steps"]}


def test_normal_job_completes_and_tracks_the_plan(project):
    code, out = cli_json("dry-run", *project)
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
    code, out = cli_json("dry-run", *project, "--inject", "grip_miss@grip")
    assert (code, out["result_code"]) == (1, 1)
    assert statuses(out)[4] == ("grip", "failed", 2)
    assert out["retries"] == 1
    assert "jaws_closed not true within 1 s" in out["steps"][3]["message"]


def test_part_slip_in_transit_is_part_lost(project):
    code, out = cli_json("dry-run", *project, "--inject", "part_slip@approach#2")
    assert (code, out["result_code"]) == (1, 2)
    assert statuses(out)[6][1] == "failed"


def test_protective_stop_is_held_then_resumed_after_5s(project):
    _, normal = cli_json("dry-run", *project)
    code, out = cli_json("dry-run", *project, "--inject", "protective_stop@approach#2")
    assert (code, out["result_code"]) == (0, 0), out
    assert all(s["status"] == "ok" for s in out["steps"])
    assert out["cycle_time_s"] >= normal["cycle_time_s"] + 5.0  # the controller's unlock delay
    assert out["max_tracking_error_m"] < 0.005


def test_second_protective_stop_beyond_max_is_100(project):
    code, out = cli_json(
        "dry-run",
        *project,
        "--inject",
        "protective_stop@approach#1",
        "--inject",
        "protective_stop@approach#2",
    )
    assert (code, out["result_code"]) == (1, 100)


def test_estop_aborts_with_101(project):
    code, out = cli_json("dry-run", *project, "--inject", "estop@move#2")
    assert (code, out["result_code"]) == (1, 101)
    assert statuses(out)[10][1] == "failed"


def test_robot_disconnect_is_102(project):
    code, out = cli_json("dry-run", *project, "--inject", "robot_disconnect@lift")
    assert (code, out["result_code"]) == (1, 102)


def test_bad_injection_is_exit_2(project):
    cell, task = project
    r = cli("dry-run", str(cell), str(task), "--inject", "grip_mis@grip", timeout_s=120)
    assert r.returncode == 2
    assert "unknown fault 'grip_mis'; known: grip_miss, part_slip" in r.stderr


def test_report_has_pictures_and_plots(project, tmp_path):
    code, _out = cli_json("dry-run", *project, "--report", str(tmp_path / "rep"))
    assert code == 0
    files = {p.name for p in (tmp_path / "rep").iterdir()}
    assert {"result.json", "joints.png", "tcp_path.png", "end.png"} <= files
    assert any(name.startswith("step") and name.endswith("_grip.png") for name in files)
    assert (tmp_path / "rep" / "end.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "rep" / "result.json").read_text())["result_code"] == 0


def test_json_logs_are_bound_with_cell_job_step_attempt(project):
    cell, task = project
    r = cli("--log-format", "json", "dry-run", str(cell), str(task), "--inject", "grip_miss@grip")
    events = [json.loads(line) for line in r.stderr.splitlines() if line.startswith("{")]
    steps = [e for e in events if e["event"] == "step"]
    assert steps and all(
        {"cell", "job_id", "step", "attempt", "timestamp"} <= set(e) for e in steps
    )
    assert {e["cell"] for e in events} == {"dryrun-cell"}
    assert max(e["attempt"] for e in steps if e["step"] == 4) == 2  # the grip's retry
    assert any(e["event"] == "retry" for e in events)
    assert events[-1]["event"] == "job_end" and events[-1]["result_code"] == 1
