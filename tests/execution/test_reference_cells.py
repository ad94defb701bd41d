"""The reference cells (cells/cnc_tending_ur5e.yaml, cells/vision_pick_ur10e.yaml) in
dry-run: the normal job, every fault that applies with its SPEC code, on_error, and a
twin that gives the same result and step table every time (SPEC section 11)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cellrunner.cli.main import main
from tests.conftest import ROOT

CNC = ("cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml")
VISION = ("cells/vision_pick_ur10e.yaml", "tasks/vision_pick.yaml")
PALLETIZER = ("cells/palletizer_ur10e.yaml", "tasks/palletize.yaml")
PEG = ("cells/peg_ur3e.yaml", "tasks/peg_insert.yaml")
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

N_CNC = 45  # expanded steps of the job; on_error's three come after


def test_cnc_normal_job_changes_grippers_waits_on_the_machine_and_completes(project):
    r = dry_run(project, CNC)
    assert (r["result_code"], r["result_text"]) == (0, "OK")
    rows = {s["index"]: s for s in r["steps"]}
    assert len(rows) == N_CNC  # no on_error rows when nothing failed
    assert rows[8]["name"] == "door_open" and rows[8]["duration_s"] == pytest.approx(
        1.5, abs=0.01
    )  # follows, 1.5 s
    assert rows[16]["name"] == "cnc_start=True" and rows[16]["duration_s"] == pytest.approx(
        0.2, abs=0.01
    )  # pulse
    # the raw-part gripper goes to the rack and the finished-part one is locked while the
    # machine cuts; the cycle-done lamp lights 4 s after the start pulse rose
    assert [(rows[i]["kind"], rows[i]["name"]) for i in (19, 23, 39, 43)] == [
        ("tool_unlock", "raw"),
        ("tool_lock", "finished"),
        ("tool_unlock", "finished"),
        ("tool_lock", "raw"),
    ]
    assert rows[25]["name"] == "cycle_done"
    assert sum(rows[i]["duration_s"] for i in range(16, 26)) == pytest.approx(4.0, abs=0.01)
    assert r["parts_end_m"]["blank"] == pytest.approx([0.25, -0.30, 0.93], abs=0.003)  # outfeed
    assert r["max_tracking_error_m"] < 0.002


ON_ERROR_ROWS = [
    ("set_output", "door_cmd=False, cnc_start=False", "ok"),
    ("lift", "lift", "ok"),
    ("move", "home", "ok"),
]


@pytest.mark.parametrize(
    "fault, code, text, failed_step",
    [
        (
            "grip_miss@grip",
            1,
            "raw_closed not true within 1 s (jaws closed on nothing); on_error done",
            5,
        ),
        (  # the finished-part gripper, at the vise
            "grip_miss@grip#2",
            1,
            "finished_closed not true within 1 s (jaws closed on nothing); on_error done",
            30,
        ),
        (
            "part_slip@approach#2",
            2,
            "part lost in transit: the jaw sensor dropped; on_error done",
            9,
        ),
        (
            "part_slip@approach#6",
            2,
            "part lost in transit: the jaw sensor dropped; on_error done",
            32,
        ),
        ("protective_stop@approach#2", 0, "OK", None),
        ("protective_stop@descend#3", 0, "OK", None),  # at the rack, while the machine cuts
        ("plc_disconnect@approach#2", 0, "OK", None),
        ("estop@move#2", 101, "e-stop during step 13 move 'home'", 13),
        (
            "robot_disconnect@lift",
            102,
            "robot connection lost; the twin's robot link was cut (robot_disconnect) and "
            "stays down",
            6,
        ),
    ],
)
def test_cnc_faults_give_their_codes_and_clean_up(project, fault, code, text, failed_step):
    r = dry_run(project, CNC, "--inject", fault)
    assert (r["result_code"], r["result_text"]) == (code, text)
    failed = [s["index"] for s in r["steps"] if s["status"] == "failed"]
    assert failed == ([failed_step] if failed_step else [])
    cleanup = [(s["kind"], s["name"], s["status"]) for s in r["steps"] if s["index"] > N_CNC]
    if text.endswith("on_error done"):  # outputs off, backed out, home
        assert cleanup == ON_ERROR_ROWS
    else:  # OK, or the arm cannot move: no on_error
        assert cleanup == []


def test_cnc_door_that_stays_shut_times_out_and_on_error_backs_out_with_the_blank(project):
    r = dry_run(project, CNC, "-p", "door_time=1 s")  # the door takes 1.5 s
    assert (r["result_code"], r["result_text"]) == (
        105,
        "input door_open did not read True within 1 s; on_error done",
    )
    assert [(s["kind"], s["name"], s["status"]) for s in r["steps"] if s["index"] > N_CNC] == (
        ON_ERROR_ROWS
    )
    assert r["parts_end_m"]["blank"][2] > 1.0  # still in the raw-part gripper, lifted with it


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
    assert r["result_code"] == 100
    assert re.fullmatch(
        "protective stop during step 5 descend 'camera_zone\\+part_pose': pad 'jaw_[ab]' met part "
        "'widget' at [0-9]+ N: more than 1 protective stops, both with the TCP within [0-9]+ mm: "
        "something there stops the arm each time",
        r["result_text"],
    ), r["result_text"]


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
        pytest.param(CNC, "protective_stop@descend#3", id="cnc-held-at-the-rack"),
        pytest.param(VISION, "protective_stop@approach#2", id="vision-stop"),
        pytest.param(CNC, "plc_disconnect@approach#2", id="cnc-plc"),
        pytest.param(PALLETIZER, "plc_disconnect@approach#2", id="palletizer-plc"),
        pytest.param(PALLETIZER, "part_slip@approach#2", id="palletizer-slip"),
        pytest.param(PEG, "protective_stop@insert", id="peg-stop"),
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
