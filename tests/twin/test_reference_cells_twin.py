"""The reference cells through the virtual controller: `cellrunner twin CELL` in its own
process (its sim: rules play the machine and the camera's part) and `cellrunner run
--backend ur`, i.e. the unmodified ur_rtde client, over loopback."""

from __future__ import annotations

import pytest

from tests.rig import fault_once_moving, run_ur, twin

CNC = ("cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml")
VISION = ("cells/vision_pick_ur10e.yaml", "tasks/vision_pick.yaml")
SEEN = '{"xyz": [0.03, -0.02, 0], "rpy": [0, 0, 20]}'


@pytest.fixture
def cnc_twin():
    with twin(CNC[0], "127.0.0.120"):
        yield "127.0.0.120"


@pytest.fixture
def vision_twin():
    with twin(VISION[0], "127.0.0.121"):
        yield "127.0.0.121"


def test_cnc_tending_through_ur_rtde_on_the_twin(cnc_twin):
    out = run_ur(*CNC, cnc_twin)
    assert (out["backend"], out["result_code"]) == ("ur", 0), out["result_text"]
    rows = {s["index"]: s for s in out["steps"]}
    assert all(s["status"] == "ok" for s in out["steps"]) and len(rows) == 45
    # the twin's sim: rules answered over RTDE: the door after 1.5 s, the cycle-done lamp
    # 4 s after the start pulse (the tool change to the finished-part gripper runs
    # meanwhile: when it took longer, the lamp was on when the wait began)
    assert rows[8]["duration_s"] == pytest.approx(1.5, abs=0.1)
    assert (rows[19]["name"], rows[23]["name"]) == ("raw", "finished")
    since_start = sum(rows[i]["duration_s"] for i in range(16, 26))
    assert since_start > 3.85
    assert since_start < 4.15 or rows[25]["duration_s"] < 0.1, (since_start, rows[25])


def test_cnc_door_timeout_on_the_twin_runs_on_error_through_ur_rtde(cnc_twin):
    out = run_ur(*CNC, cnc_twin, "-p", "door_time=1 s")  # the door takes 1.5 s
    assert (out["result_code"], out["result_text"]) == (
        105,
        "input door_open did not read True within 1 s; on_error done",
    )
    assert [(s["kind"], s["status"]) for s in out["steps"] if s["index"] > 45] == [
        ("set_output", "ok"),
        ("lift", "ok"),
        ("move", "ok"),
    ]


def test_cnc_estop_on_the_twin_is_101_without_cleanup(cnc_twin):
    fault_once_moving(cnc_twin, "estop press")  # the job (23 s) is under way, not yet done
    out = run_ur(*CNC, cnc_twin)
    assert out["result_code"] == 101
    assert out["result_text"].startswith("e-stop during step ")
    assert all(s["index"] <= 45 for s in out["steps"])  # the arm cannot move: no on_error


def test_vision_pick_through_ur_rtde_with_the_pose_param(vision_twin):
    out = run_ur(*VISION, vision_twin, "-p", f"part_pose={SEEN}")
    assert (out["result_code"], out["result_text"]) == (0, "OK")


def test_vision_pick_where_the_part_is_not_on_the_twin(vision_twin):
    out = run_ur(
        *VISION, vision_twin, "-p", 'part_pose={"xyz": [-0.04, 0.05, 0], "rpy": [0, 0, 0]}'
    )
    assert out["result_code"] == 1
    assert (
        out["result_text"]
        == "jaws_closed not true within 1 s (jaws closed on nothing); on_error done"
    )
