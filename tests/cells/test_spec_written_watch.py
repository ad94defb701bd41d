"""A watched cell written from SPEC.md section 12 alone (issue 25, judged by): a UR16e on a
shared bench under an overhead depth camera (tests/cells/spec_written/cells/watched_ur16e.yaml).
The totes are rehearsal intruders (`sim: {intruders}`) added to that cell here, one per
scenario; only the twin's depth camera reveals them.

Timeline of the job (check): approach the infeed 0-1.9 s, grip, lift until 3.1 s, the
transfer to the tray (step 6) 3.1-4.3 s. A tote on the transfer's path appears at 2.3 s,
while the arm is at the infeed, 0.4 m from it.
"""

from __future__ import annotations

import math

import pytest

from tests.cells.spec_written_rig import HERE, cli

TRAY = (0.55, 0.35, 0.93)  # the housing's middle, set down in the tray
ON_THE_PATH = "{name: tote, box: {size: [0.30, 0.20, 0.30]}, pose: {xyz: [0.65, 0.0, 1.05]}"
BESIDE_THE_PATH = "{name: tote, box: {size: [0.30, 0.20, 0.15]}, pose: {xyz: [0.95, -0.35, 0.975]}"


def watched(tmp_path, intruder: str | None = None) -> str:
    """The watched cell, with one intruder in its sim: block (beside its tasks)."""
    text = (HERE / "cells" / "watched_ur16e.yaml").read_text()
    if intruder is not None:
        anchor = "  depth_noise: 0.002\n"
        assert anchor in text
        text = text.replace(anchor, f"{anchor}  intruders:\n    - {intruder}\n")
    for sub in ("cells", "tasks"):
        (tmp_path / sub).mkdir(exist_ok=True)
    for path in (HERE / "tasks").glob("watched_*.yaml"):
        (tmp_path / "tasks" / path.name).write_text(path.read_text())
    path = tmp_path / "cells" / "watched.yaml"
    path.write_text(text)
    return str(path)


def transfer(replan: bool = False) -> str:
    name = "watched_transfer_replan" if replan else "watched_transfer"
    return str(HERE / "tasks" / f"{name}.yaml")


def stops(out: dict) -> list[str]:
    return [event["what"] for event in out.get("obstacles", [])]


@pytest.mark.parametrize(
    "intruder", [None, BESIDE_THE_PATH + ", appear: 0.3}"], ids=["static", "tote_beside_the_path"]
)
def test_nothing_in_the_way_costs_nothing(tmp_path, intruder):
    code, out = cli("dry-run", watched(tmp_path, intruder), transfer())
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    assert stops(out) == []
    assert out["cycle_time_s"] <= 1.03 * out["planned_cycle_time_s"]
    assert math.dist(out["parts_end_m"]["housing"], TRAY) < 0.005


def test_a_tote_on_the_path_for_4_s_makes_the_arm_wait_then_finish(tmp_path):
    code, out = cli(
        "dry-run", watched(tmp_path, ON_THE_PATH + ", appear: 2.3, leave: 6.3}"), transfer()
    )
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    assert "wait" in stops(out) and "clear" in stops(out), out["obstacles"]
    assert out["cycle_time_s"] > out["planned_cycle_time_s"] + 2.0
    assert math.dist(out["parts_end_m"]["housing"], TRAY) < 0.005


def test_a_tote_that_stays_ends_the_job_with_108_without_touching_it(tmp_path):
    code, out = cli("dry-run", watched(tmp_path, ON_THE_PATH + ", appear: 2.3}"), transfer())
    assert (code, out["result_code"]) == (1, 108), out["result_text"]
    assert "tote" not in out["result_text"]  # found by the camera, not read from the file


# Totes that stay on the transfer's path, clear of the poses the job must reach: a low one
# the arm can pass over, a tall one it must go round.
STAYING = {
    "low": "{name: tote, box: {size: [0.30, 0.20, 0.15]}, pose: {xyz: [0.65, 0.0, 0.975]}",
    "tall": "{name: tote, box: {size: [0.30, 0.20, 0.30]}, pose: {xyz: [0.75, 0.0, 1.05]}",
}


@pytest.mark.parametrize("tote", STAYING.values(), ids=STAYING.keys())
def test_a_tote_that_stays_is_gone_round_with_replanning(tmp_path, tote):
    cell = watched(tmp_path, tote + ", appear: 2.3}")
    code, out = cli("dry-run", cell, transfer())
    assert (code, out["result_code"]) == (1, 108), out["result_text"]
    code, out = cli("dry-run", cell, transfer(replan=True))
    assert (code, out["result_code"]) == (0, 0), (out["result_text"], out["obstacles"])
    assert "replan" in stops(out) and "clear" not in stops(out), out["obstacles"]
    assert out["intruders_touched"] == []
    assert math.dist(out["parts_end_m"]["housing"], TRAY) < 0.005


def test_a_tote_under_the_home_pose_ends_108_naming_the_goal(tmp_path):
    """The tall tote on the path reaches within the padding of where the tool stands at
    home: the part is placed round it, but no plan can end at home."""
    code, out = cli(
        "dry-run", watched(tmp_path, ON_THE_PATH + ", appear: 2.3}"), transfer(replan=True)
    )
    assert (code, out["result_code"]) == (1, 108), out["result_text"]
    assert "move 'home'" in out["result_text"]
    assert math.dist(out["parts_end_m"]["housing"], TRAY) < 0.005
    whys = [e.get("why", "") for e in out["obstacles"] if e["what"] == "replan failed"]
    assert any("its goal is within the padding" in why for why in whys), out["obstacles"]
    assert out["intruders_touched"] == []


# --inject intrusion@STEP: (step, replan, the results that leave the box untouched).
DROPPED = {
    "transfer_wait": ("approach#2", False, {0, 108}),
    # the move home lifts the tool up past where the wrist stands: the box drops once
    # there is room for it clear of the arm (it used to drop onto the arm: 100)
    "home_wait": ("move#2", False, {108}),
    "home_replan": ("move#2", True, {0, 108}),
}


@pytest.mark.parametrize("case", DROPPED.values(), ids=DROPPED.keys())
def test_a_box_dropped_on_the_path_is_never_touched(case):
    """SPEC 12: --inject intrusion@STEP drops a box onto the path of STEP while it runs;
    the arm stops short of it (no protective stop, 100); with replanning it goes round."""
    step, replan, results = case
    code, out = cli(
        "dry-run",
        str(HERE / "cells" / "watched_ur16e.yaml"),
        transfer(replan),
        "--inject",
        f"intrusion@{step}",
    )
    assert out["result_code"] in results, (out["result_text"], out.get("obstacles"))
    assert code == (0 if out["result_code"] == 0 else 1)
    assert not any("nothing was dropped" in e for e in out["errors"]), out["errors"]
    assert "stop" in stops(out), out["obstacles"]  # stopped short of it on its path
    assert out["intruders_touched"] == []
