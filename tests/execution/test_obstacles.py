"""Jobs that meet an obstacle not in the cell file (SPEC 12), rehearsed on the twin: a tote
only the overhead depth camera sees. It stands on the path for 4 s: the arm stops on its
path, waits and finishes (0); it stays: 108 without replanning, and gone round (0) with
replanning; the arm never touches it (a touch would be a protective stop, 100)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

WATCHED = ROOT / "cells" / "watched_ur5e.yaml"
#: a tote dropped on the approach's path 0.3 s into the job
TOTE = "{name: tote, box: {size: [0.2, 0.14, 0.1]}, pose: {xyz: [0.52, -0.24, 1.1]}, appear: 0.3"
#: a tote that stands on the approach's path from the start, with room to go round it
TOTE_AROUND = "{name: tote, box: {size: [0.16, 0.16, 0.1]}, pose: {xyz: [0.64, -0.05, 1.2]}"


def tote_cell(tmp_path: Path, leave: str = "", tote: str = TOTE) -> Path:
    text = WATCHED.read_text().replace(
        "sim:\n  depth_noise: 0.002\n",
        f"sim:\n  depth_noise: 0.002\n  intruders:\n    - {tote}{leave}}}\n",
    )
    text = text.replace("tasks/", f"{ROOT}/tasks/")
    path = tmp_path / "tote.yaml"
    path.write_text(text)
    return path


def dry_run(cell: Path, task: str, *extra: str) -> dict:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "dry-run",
            str(cell),
            str(ROOT / "tasks" / task),
            "--json",
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env={"MUJOCO_GL": "disable", "PATH": "/usr/bin:/bin"},
        cwd=ROOT,
    )
    assert done.stdout, done.stderr
    return json.loads(done.stdout)


def whats(result: dict) -> list[str]:
    return [e["what"] for e in result.get("obstacles", [])]


def test_a_static_watched_cell_never_stops_and_its_placed_part_is_known(tmp_path):
    from cellrunner.perception.occupancy import OccupancyMap

    result = dry_run(WATCHED, "pick_place_watched.yaml", "--save-map", str(tmp_path / "m.npz"))
    assert result["result_code"] == 0 and whats(result) == []
    assert result["cycle_time_s"] <= result["planned_cycle_time_s"] * 1.03
    assert result["depth_images"] > 100  # 15 Hz over a 7.6 s job
    # the block set down on the pallet is the cell file's part, where the arm released it
    assert len(OccupancyMap.load(tmp_path / "m.npz").occupied()) == 0


def test_a_tote_on_the_path_for_four_seconds_makes_the_arm_wait(tmp_path):
    result = dry_run(tote_cell(tmp_path, ", leave: 4.3"), "pick_place.yaml")
    assert result["result_code"] == 0, result["result_text"]
    events = whats(result)
    assert events[0] in ("stop", "blocked before start") and "wait" in events and "clear" in events
    clear = next(e for e in result["obstacles"] if e["what"] == "clear")
    assert 4.3 <= clear["time_s"] <= 5.5  # seen free within a second of its leaving
    assert result["cycle_time_s"] > result["planned_cycle_time_s"] + 3.0
    assert result["intruders_touched"] == []


def test_a_tote_that_stays_ends_the_job_with_108_without_replanning(tmp_path):
    result = dry_run(tote_cell(tmp_path), "pick_place.yaml")
    assert result["result_code"] == 108
    assert (
        "path blocked by an obstacle not in the cell file (occupied voxel at ("
        in (result["result_text"])
    )
    assert "replan" not in whats(result)


@pytest.mark.parametrize(
    ("task", "code"), [("pick_place.yaml", 108), ("pick_place_watched.yaml", 0)]
)
def test_a_tote_that_stays_from_the_start_is_gone_round_with_replanning(tmp_path, task, code):
    result = dry_run(tote_cell(tmp_path, tote=TOTE_AROUND), task)
    assert result["result_code"] == code, result["result_text"]
    assert ("replan" in whats(result)) == (code == 0)
    # the step's journal row says what happened, when and where
    journaled = [s["message"] for s in result["steps"] if "obstacle: " in s["message"]]
    assert journaled and " s at (" in journaled[0], result["steps"]
    assert result["intruders_touched"] == []


def test_a_box_dropped_onto_the_path_is_seen_only_by_the_depth_camera():
    result = dry_run(WATCHED, "pick_place.yaml", "--inject", "intrusion@2")
    assert result["result_code"] == 108, result["result_text"]
    assert whats(result)[:2] == ["stop", "wait"]
    assert result["intruders_touched"] == []
