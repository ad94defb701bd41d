"""What a person sees when a cell is wrong: the blocking fixture and link named, one
line per group of identical slot failures, a "did you mean" for every unit slip, and
--json's one object even for refused input. The cells are in tests/data/diagnostics/."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.conftest import ROOT

DATA = ROOT / "tests" / "data" / "diagnostics"
#: how the files are named in messages (relative to the working directory, the repository)
REL = "tests/data/diagnostics"


def cellrunner(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        env={"OMP_NUM_THREADS": "1", "COLUMNS": "200", "PATH": "/usr/bin:/bin"},
    )


def test_conveyor_near_the_shoulder_is_named_with_the_links_it_blocks():
    r = cellrunner(
        "check",
        str(DATA / "conveyor_near_shoulder.yaml"),
        str(ROOT / "tasks" / "pick_place.yaml"),
        "--json",
        "--no-cache",
    )
    assert r.returncode == 1, r.stderr
    out = json.loads(r.stdout)
    first = out["errors"][0]
    assert first.startswith(
        "step 2 approach 'infeed': every IK branch collides, 8 of 8 with fixture 'conveyor' "
        "(mostly the "
    ), first
    assert first.count("elbow up") + first.count("elbow down") == 8  # each branch and why
    assert "forearm in fixture 'conveyor'" in first and "mm deep" in first
    assert first.endswith(
        "fix: move the frame away from fixture 'conveyor', or approach from another direction "
        "(turn the frame's rpy)"
    )
    # the same failure on all twelve slots is one group
    assert [(g["param"], g["slots"]) for g in out["failed_slots"]] == [("slot", list(range(12)))]


def test_console_prints_one_line_per_group_of_slots_and_keeps_bracketed_names():
    r = cellrunner(
        "check", str(DATA / "conveyor_near_shoulder.yaml"), str(ROOT / "tasks" / "pick_place.yaml")
    )
    assert r.returncode == 1
    assert (
        r.stderr.count("infeasible: slots 0-11: step 2 approach 'infeed': every IK branch collides")
        == 1
    )
    assert r.stderr.count("every IK branch collides") == 2  # the table's headline and the group
    assert "pallet[slot=0]" in r.stderr  # rich markup no longer eats [slot=0]


def test_approach_written_in_mm_gets_a_did_you_mean_at_load_and_in_the_failure():
    r = cellrunner(
        "check", str(DATA / "approach_mm_cell.yaml"), str(DATA / "approach_mm_task.yaml"), "--json"
    )
    assert r.returncode == 1
    task = f"{REL}/approach_mm_task.yaml"
    assert (
        f"{task}:6:34: warning: steps[1].pick.approach: 150 m is longer than the UR5e's reach (0.85 m); "
        "did you mean 150 mm = 0.15 m? (write '150 mm')"
    ) in r.stderr
    out = json.loads(r.stdout)
    assert out["failed_slots"][0]["slots"] == list(range(12))
    assert out["failed_slots"][0]["error"].endswith(
        "the approach distance 150 m is longer than the reach: did you mean 150 mm = 0.15 m? (write '150 mm')"
    )
    assert any("did you mean 150 mm" in w for w in out["warnings"])


def test_every_unit_slip_in_a_cell_and_task_gets_a_did_you_mean():
    r = cellrunner("validate", str(DATA / "mm_cell.yaml"), str(DATA / "mm_task.yaml"))
    cell, task = f"{REL}/mm_cell.yaml", f"{REL}/mm_task.yaml"
    assert r.returncode == 0, r.stderr
    lines = [line for line in r.stderr.splitlines() if ": warning: " in line]
    expected = [
        (f"{cell}:9:14: warning: tool.tcp.xyz: ", "did you mean mm, i.e. [0, 0, 0.15] m?"),
        (
            f"{cell}:13:31: warning: fixtures[0].box.size: ",
            "did you mean mm, i.e. [1.2, 0.8, 0.04] m?",
        ),
        (
            f"{cell}:14:5: warning: fixtures[1]: fixture 'bin' has no pose",
            "give it 'pose: {xyz: [x, y, z]}' (m)",
        ),
        (
            f"{cell}:16:17: warning: frames.infeed.xyz: frame 'infeed' is 1089.92 m from the UR5e's shoulder",
            "did you mean mm, i.e. [0.45, -0.35, 0.93] m?",
        ),
        (
            f"{cell}:17:18: warning: frames.outfeed.xyz: frame 'outfeed' is 4.00 m from the UR5e's shoulder",
            "is the cell in the wrong place, or the robot? robot.mount is at [0, 0, 0.9]; did you mean a mount "
            "near [3.4, 2.1, 0.9], among the frames?",
        ),
        (
            f"{task}:6:30: warning: steps[1].pick.approach: ",
            "did you mean 150 mm = 0.15 m? (write '150 mm')",
        ),
        (
            f"{task}:6:42: warning: steps[1].pick.speed: ",
            "did you mean 250 mm/s = 0.25 m/s? (write '250 mm/s')",
        ),
        (
            f"{task}:7:72: warning: steps[2].place.pattern.pitch: ",
            "did you mean mm, i.e. [0.07, 0.07] m?",
        ),
        (
            f"{task}:8:53: warning: steps[3].approach.offset.xyz: ",
            "did you mean mm, i.e. [0, 0, 0.12] m?",
        ),
    ]
    assert len(lines) == len(expected), "\n".join(lines)
    for line, (start, part) in zip(lines, expected, strict=True):
        assert line.startswith(start), line
        assert part in line, line


def test_the_demo_cell_draws_no_warning():
    r = cellrunner("validate", str(ROOT / "cells" / "demo_ur5e.yaml"))
    warnings = [
        line
        for line in r.stderr.splitlines()
        if ": warning: " in line and "plc.opcua.users" not in line
    ]
    assert r.returncode == 0 and not warnings, r.stderr


def test_json_prints_its_object_on_input_errors_with_exit_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("cell: x\nrobot: {model: ur6}\n")
    for command in ("check", "dry-run"):
        r = cellrunner(command, str(bad), str(ROOT / "tasks" / "pick_place.yaml"), "--json")
        assert r.returncode == 2
        out = json.loads(r.stdout)
        assert out["ok"] is False and out["steps"] == []
        assert any(
            e.startswith(f"{bad}:2:16: error: robot.model: unknown robot model 'ur6'")
            for e in out["errors"]
        ), out
    r = cellrunner(
        "check",
        str(ROOT / "cells" / "demo_ur5e.yaml"),
        str(ROOT / "tasks" / "pick_place.yaml"),
        "-p",
        "slot=12",
        "--json",
    )
    assert r.returncode == 2
    assert json.loads(r.stdout)["errors"] == [
        "cellrunner check: error: param 'slot' = 12 is outside [0, 11]"
    ]
    r = cellrunner("check", "--json", "--bogus")
    assert r.returncode == 2
    assert json.loads(r.stdout)["errors"] == ["cellrunner: error: unrecognized arguments: --bogus"]


def test_jobs_shows_whole_job_ids_at_80_columns(tmp_path):
    from cellrunner.execution.journal import Journal
    from cellrunner.model.codes import ResultCode

    (tmp_path / "c.yaml").write_text(
        "cell: c\nrobot: {model: ur5e, home: [0, -90, 90, -90, -90, 0]}\njournal: jobs.sqlite\n"
    )
    journal = Journal(tmp_path / "jobs.sqlite").open()
    job_ids = ["3f2b8c1e-9a47-4d2b-8e51-7c0d9f6a1b23", "c0ffee00-1234-4abc-9def-0123456789ab"]
    for job_id in job_ids:
        journal.begin_job(job_id, "c", "pick_place", {"slot": 7}, "plc-modbus", "client-42")
        journal.end_job(job_id, ResultCode.OK, 8.76, 0, "OK")
    journal.close()
    r = cellrunner("jobs", str(tmp_path / "c.yaml"))
    r80 = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "jobs", str(tmp_path / "c.yaml")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
        env={"COLUMNS": "80", "PATH": "/usr/bin:/bin"},
    )
    for out in (r.stderr, r80.stderr):
        for job_id in job_ids:
            assert job_id in out, out
    assert max(len(line) for line in r80.stderr.splitlines()) <= 80


def test_a_radius_and_a_tcp_speed_in_mm_get_a_did_you_mean(tmp_path):
    cell = tmp_path / "r.yaml"
    cell.write_text(
        "cell: r\nrobot:\n  model: ur5e\n  home: [0, -90, 90, -90, -90, 0]\n"
        "fixtures:\n  - {name: post, cylinder: {radius: 15, length: 0.4}, pose: {xyz: [0.5, 0, 0.2]}}\n"
    )
    r = cellrunner("validate", str(cell))
    assert r.returncode == 0
    assert (
        f"{cell}:6:37: warning: fixtures[0].cylinder.radius: 15 m is larger than any cylinder radius in a cell "
        "(over 5 m); did you mean 15 mm = 0.015 m? (write '15 mm')"
    ) in r.stderr
    cell.write_text(
        "cell: r\nrobot:\n  model: ur5e\n  home: [0, -90, 90, -90, -90, 0]\n  limits: {tcp_speed: 250}\n"
    )
    r = cellrunner("validate", str(cell))
    assert r.returncode == 2
    assert r.stderr.strip().endswith(
        "robot.limits.tcp_speed: 250 m/s is above the UR5E controller's 3 m/s; "
        "did you mean 250 mm/s = 0.25 m/s? (write '250 mm/s')"
    )
