"""The watched zone, depth cameras, intruders and on_obstacle in the cell and task files:
valid files load, mistakes are located errors naming the valid choices."""

from __future__ import annotations

from pathlib import Path

import pytest

from cellrunner.errors import InputError
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from tests.conftest import ROOT

WATCHED = ROOT / "cells" / "watched_ur5e.yaml"

CELL = """cell: c
robot: {model: ur5e, home: [0, -90, 90, -90, -90, 0]}
frames: {infeed: {xyz: [0.4, 0, 0.9]}}
cameras:
  top:
    intrinsics: {fx: 460, fy: 460, cx: 319.5, cy: 239.5}
    image_size: [640, 480]
    pose: {xyz: [0.4, 0, 2.3], rpy: [180, 0, 90]}
    DEPTH
  colour:
    intrinsics: {fx: 460, fy: 460, cx: 319.5, cy: 239.5}
    image_size: [640, 480]
watch:
  cameras: CAMERAS
  zone: {box: {size: ZONE}, pose: {xyz: [0.4, 0, 1.3]}}
SIM
"""


def cell_text(
    depth: str = "depth: {range: [0.3, 2.5], rate: 15}",
    cameras: str = "[top]",
    zone: str = "[1.6, 1.2, 1.0]",
    sim: str = "",
) -> str:
    return (
        CELL.replace("DEPTH", depth)
        .replace("CAMERAS", cameras)
        .replace("ZONE", zone)
        .replace("SIM", sim)
    )


def errors_of(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as exc:
        load_cell(path)
    return [str(d) for d in exc.value.diagnostics]


def test_the_watched_example_loads_with_its_defaults():
    loaded = load_cell(WATCHED)
    watch = loaded.cell.watch
    assert watch is not None and watch.cameras == ["overhead"]
    assert (watch.voxel, watch.occupancy.hit, watch.occupancy.miss, watch.padding) == (
        0.02,
        0.7,
        0.4,
        0.03,
    )
    depth = loaded.cell.cameras["overhead"].depth
    assert depth is not None and depth.range_m == (0.3, 2.5) and depth.rate == 15
    task = load_task(loaded.resolve(loaded.cell.tasks[1]), loaded).task
    assert (task.on_obstacle.wait, task.on_obstacle.replan, task.on_obstacle.max_replans) == (
        4,
        True,
        2,
    )


def test_on_obstacle_defaults_wait_ten_seconds_without_replanning(tmp_path):
    loaded = load_cell(WATCHED)
    task = load_task(ROOT / "tasks" / "pick_place.yaml", loaded).task
    assert (task.on_obstacle.wait, task.on_obstacle.replan) == (10.0, False)
    assert int(ResultCode.PATH_BLOCKED) == 108
    assert ResultCode.PATH_BLOCKED.text == "path blocked by an obstacle not in the cell file"


def test_a_watched_camera_without_depth_is_a_located_error(tmp_path):
    lines = errors_of(tmp_path, cell_text(cameras="[top, colour]"))
    assert lines == [
        f"{tmp_path / 'c.yaml'}:14:18: error: watch.cameras[1]: camera 'colour' has no "
        "'depth:'; depth cameras: top"
    ]


def test_an_unknown_watched_camera_names_the_known_ones(tmp_path):
    (line,) = errors_of(tmp_path, cell_text(cameras="[tpo]"))
    assert (
        "watch.cameras[0]: unknown camera 'tpo' (did you mean 'top'?); known: top, colour" in line
    )


def test_a_depth_range_must_run_from_near_to_far(tmp_path):
    (line,) = errors_of(tmp_path, cell_text(depth="depth: {range: [2.5, 0.3]}"))
    assert ":9:" in line and "range [2.5, 0.3] m must have its near end below its far end" in line


def test_a_zone_too_big_for_its_voxels_says_how_many(tmp_path):
    (line,) = errors_of(tmp_path, cell_text(zone="[40, 40, 10]"))
    assert "zone in 0.02 m voxels has 2,000,000,000 of them; the map holds at most" in line


def test_intruders_need_one_shape_and_one_place(tmp_path):
    sim = (
        "sim:\n  intruders:\n"
        "    - {name: hand, box: {size: [0.1, 0.1, 0.1]}, pose: {xyz: [0.4, 0, 1]}, at: infeed}\n"
        "    - {name: bar, box: {size: [0.1, 0.1, 0.1]}, pose: {xyz: [0.4, 0, 1]}, appear: 3, leave: 2}\n"
    )
    first, second = errors_of(tmp_path, cell_text(sim=sim))
    assert "sim.intruders[0]: an intruder needs exactly one of pose, at (a frame)" in first
    assert "sim.intruders[1]: leave 2 s must come after appear 3 s" in second


def test_intruders_name_known_frames_once_each(tmp_path):
    sim = (
        "sim:\n  intruders:\n"
        "    - {name: tote, box: {size: [0.4, 0.3, 0.2]}, at: infed, appear: 1}\n"
        "    - {name: tote, box: {size: [0.4, 0.3, 0.2]}, pose: {xyz: [0.4, 0, 1]}}\n"
    )
    first, second = errors_of(tmp_path, cell_text(sim=sim))
    assert "sim.intruders[0].at: unknown frame 'infed' (did you mean 'infeed'?)" in first
    assert "sim.intruders[1].name: intruder 'tote' is listed twice" in second
