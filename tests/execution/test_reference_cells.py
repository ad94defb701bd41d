"""The reference cells (cells/cnc_tending_ur5e.yaml, cells/vision_pick_ur10e.yaml) in
dry-run: the normal job, every fault that applies with its SPEC code, on_error, and a
twin that gives the same result and step table every time (SPEC section 11)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cellrunner.cli.main import main
from tests.conftest import ROOT

pytest.importorskip("mujoco")

CNC = ("cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml")
VISION = ("cells/vision_pick_ur10e.yaml", "tasks/vision_pick.yaml")
REPEATS = 20


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """A copy of the reference files with an empty plan cache: the first run plans."""
    root = tmp_path_factory.mktemp("reference")
    for folder in ("cells", "tasks"):
        shutil.copytree(ROOT / folder, root / folder)
    return root


def dry_run(project: Path, files: tuple[str, str], *args: str) -> dict:
    """``cellrunner dry-run --json`` in this process (unpaced, as the CLI runs it)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(["dry-run", *(str(project / f) for f in files), *args, "--json"])
    result = json.loads(out.getvalue())
    assert code == (0 if result["result_code"] == 0 else 1)
    return result


def table(result: dict) -> list:
    """What must not change between identical runs: the code, its text, every row."""
    return [
        result["result_code"],
        result["result_text"],
        result["cycle_time_s"],
        [
            (s["index"], s["status"], s["duration_s"], s["attempts"], s["message"])
            for s in result["steps"]
        ],
    ]


def statuses(result: dict, first: int, last: int) -> list[str]:
    return [s["status"] for s in result["steps"] if first <= s["index"] <= last]


# -- CNC tending ---------------------------------------------------------------------------


def test_cnc_normal_job_waits_on_the_machine_and_completes(project):
    r = dry_run(project, CNC)
    assert (r["result_code"], r["result_text"]) == (0, "OK")
    rows = {s["index"]: s for s in r["steps"]}
    assert len(rows) == 29  # no on_error rows when nothing failed
    assert rows[8]["name"] == "door_open" and rows[8]["duration_s"] == pytest.approx(
        1.5, abs=0.01
    )  # follows, 1.5 s
    assert rows[16]["name"] == "cnc_start=True" and rows[16]["duration_s"] == pytest.approx(
        0.2, abs=0.01
    )  # pulse
    assert rows[17]["name"] == "cycle_done" and rows[17]["duration_s"] == pytest.approx(
        3.8, abs=0.01
    )  # 4 s after
    assert r["max_tracking_error_m"] < 0.002


@pytest.mark.parametrize(
    "fault, code, text",
    [
        (
            "grip_miss@grip",
            1,
            "gripper_closed not true within 1 s (jaws closed on nothing); on_error done",
        ),
        ("part_slip@approach#2", 2, "part lost in transit: the jaw sensor dropped; on_error done"),
        ("protective_stop@approach#2", 0, "OK"),
        ("plc_disconnect@approach#2", 0, "OK"),
        ("estop@move#2", 101, "e-stop during step 13 move 'home'"),
        (
            "robot_disconnect@lift",
            102,
            "robot connection lost; the twin's robot link was cut (robot_disconnect) and "
            "stays down",
        ),
    ],
)
def test_cnc_faults_give_their_codes_and_clean_up(project, fault, code, text):
    r = dry_run(project, CNC, "--inject", fault)
    assert (r["result_code"], r["result_text"]) == (code, text)
    if text.endswith("on_error done"):  # door command dropped, backed out, home
        assert [(s["kind"], s["name"], s["status"]) for s in r["steps"] if s["index"] > 29] == [
            ("set_output", "door_cmd=False, cnc_start=False", "ok"),
            ("retreat", "retreat", "ok"),
            ("move", "home", "ok"),
        ]
    elif code >= 100:  # the arm cannot move: no on_error
        assert all(s["index"] <= 29 for s in r["steps"])


def test_cnc_machine_that_never_finishes_times_out_and_on_error_goes_on_past_a_failed_step(project):
    r = dry_run(project, CNC, "-p", "cycle_time=2 s")
    assert r["result_code"] == 105
    assert r["result_text"] == (
        "input cycle_done did not read True within 2 s; on_error failed: step 31 retreat: "
        "line needs a configuration flip 4 mm along the 30 mm line (joint 6 jumps 150 deg "
        "between samples)"
    )
    assert statuses(r, 30, 32) == ["ok", "failed", "ok"]  # the door output is off, the arm at home


# -- vision pick ---------------------------------------------------------------------------

SEEN = '{"xyz": [0.03, -0.02, 0], "rpy": [0, 0, 20]}'  # where the twin's part lies


def test_vision_pick_at_the_pose_the_camera_gives(project):
    r = dry_run(project, VISION, "-p", f"part_pose={SEEN}", "-p", "settle=150 ms")
    assert (r["result_code"], r["result_text"]) == (0, "OK")
    assert r["params"] == {
        "part_pose": {"xyz": [0.03, -0.02, 0.0], "rpy": [0.0, 0.0, 20.0]},
        "settle": 0.15,
    }
    assert r["steps"][3]["name"] == "camera_zone+part_pose"


def test_vision_pick_where_the_part_is_not_finds_nothing(project):
    r = dry_run(project, VISION, "-p", 'part_pose={"xyz": [-0.04, 0.05, 0], "rpy": [0, 0, 0]}')
    assert (r["result_code"], r["result_text"]) == (
        1,
        "jaws_closed not true within 1 s (jaws closed on nothing); on_error done",
    )
    assert r["steps"][5]["attempts"] == 2  # the retry went to the same (wrong) place


def test_vision_pick_with_the_fingers_landing_on_the_part_is_a_contact(project):
    r = dry_run(project, VISION, "-p", 'part_pose={"xyz": [0, 0, 0], "rpy": [0, 0, 0]}')
    assert (r["result_code"], r["result_text"]) == (
        100,
        "protective stop during step 5 descend 'camera_zone+part_pose': more than 1 protective stops",
    )


@pytest.mark.parametrize(
    "fault, code",
    [
        ("grip_miss@grip", 1),
        ("part_slip@approach#2", 2),
        ("protective_stop@approach#2", 0),
        ("plc_disconnect@approach#2", 0),
        ("estop@approach#2", 101),
        ("robot_disconnect@lift", 102),
    ],
)
def test_vision_faults_give_their_codes(project, fault, code):
    assert dry_run(project, VISION, "--inject", fault)["result_code"] == code


def test_vision_pose_outside_its_box_is_an_input_error(project, capsys):
    assert (
        main(
            ["dry-run", *(str(project / f) for f in VISION), "-p", 'part_pose={"xyz": [0.2, 0, 0]}']
        )
        == 2
    )
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            "cellrunner dry-run: error: param 'part_pose' x = 0.2 m is outside [-0.06, 0.06] m"
        )
    )


# -- a deterministic twin ------------------------------------------------------------------


@pytest.mark.parametrize(
    "files, fault",
    [
        (CNC, "protective_stop@approach#2"),
        (VISION, "protective_stop@approach#2"),
        (CNC, "plc_disconnect@approach#2"),
    ],
)
def test_twenty_identical_dry_runs_give_identical_results(tmp_path, files, fault):
    for folder in ("cells", "tasks"):
        shutil.copytree(ROOT / folder, tmp_path / folder)
    first = table(dry_run(tmp_path, files, "--inject", fault))  # planned afresh
    for _ in range(REPEATS - 1):  # then from the plan cache
        assert table(dry_run(tmp_path, files, "--inject", fault)) == first


def test_runs_in_other_processes_with_other_hash_seeds_agree(project):
    """Nothing in the twin may depend on set or dict order across processes."""
    results = []
    for seed in ("1", "2"):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "dry-run",
                *(str(project / f) for f in CNC),
                "--inject",
                "part_slip@approach#2",
                "--json",
            ],
            capture_output=True,
            text=True,
            timeout=300,
            env={**os.environ, "PYTHONHASHSEED": seed, "MUJOCO_GL": "osmesa"},
        )
        results.append(table(json.loads(proc.stdout)))
    assert results[0] == results[1]
