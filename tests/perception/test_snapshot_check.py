"""check --watch SNAPSHOT: the task is planned against a saved obstacle map too."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from cellrunner.model.expand import frame_pose
from cellrunner.model.load import load_cell
from cellrunner.perception.occupancy import OccupancyMap
from tests.conftest import ROOT

CELL = ROOT / "cells" / "watched_ur5e.yaml"
TASK = ROOT / "tasks" / "pick_place.yaml"


def snapshot(path, centre_m, half_m=0.04):
    """A map of the cell's zone with a cube of occupied voxels around ``centre_m``."""
    watch = load_cell(CELL).cell.watch
    m = OccupancyMap(watch.zone.pose.matrix(), tuple(watch.zone.box.size), watch.voxel)
    r = np.arange(-half_m, half_m + 1e-9, watch.voxel)
    cube = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3) + centre_m
    index = m.index_of(cube)
    m.log_odds[index[index >= 0]] = 2.0
    m.save(path)
    return path


def check(*args):
    return subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "check", str(CELL), str(TASK), *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )


def test_an_obstacle_on_the_infeed_makes_the_task_infeasible(tmp_path):
    infeed = frame_pose(load_cell(CELL).cell, "infeed")[:3, 3]
    done = check("--watch", str(snapshot(tmp_path / "m.npz", infeed + (0, 0, 0.12))), "--json")
    assert done.returncode == 1, done.stderr
    result = json.loads(done.stdout)
    assert any("watched zone" in e for e in result["errors"]), result["errors"]


def test_a_bad_snapshot_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "m.npz").write_text("not a map")
    done = check("--watch", str(tmp_path / "m.npz"))
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"cellrunner check: error: --watch {tmp_path / 'm.npz'}: not a map snapshot "
        "(dry-run or serve --save-map writes one)"
    ]
