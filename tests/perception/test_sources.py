"""Depth sources on the arm: recorded images replayed into the watched zone's map, and the
twin's depth cameras over the network feeding `run --backend ur` through the virtual
controller."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from cellrunner.backends.base import RobotState, Safety
from cellrunner.errors import UsageError
from cellrunner.execution.watch import watch_on_sources
from cellrunner.model.load import load_cell
from cellrunner.perception.sources import depth_source
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT
from tests.twin.cell_rig import cli, twin

CELL = ROOT / "cells" / "watched_ur5e.yaml"


class _Arm:
    """What the feed reads from the control loop: the arm standing at home."""

    def __init__(self, q_rad):
        state = RobotState(0.0, np.asarray(q_rad), np.zeros(6), np.zeros(6), Safety.NORMAL)
        self.backend = type("B", (), {"read_state": staticmethod(lambda: state)})()


def test_replayed_images_fill_the_map(tmp_path):
    loaded = load_cell(CELL)
    world = CellWorld(loaded)
    (tmp_path / "overhead").mkdir()
    table = np.full((480, 640), 1.38, np.float32)  # the table top, 1.38 m under the camera
    boxed = table.copy()
    boxed[60:120, 80:160] = 1.0  # a box's top, 0.38 m above the table
    # the box twice: a replay loops, and a table image after the third (a loaded machine
    # may integrate a fourth before the feed closes) sees through the box's voxels once
    for k, image in enumerate([table, boxed, boxed]):
        np.save(tmp_path / "overhead" / f"{k:03d}.npy", image)
    watched = watch_on_sources(world, f"replay:{tmp_path}", None)
    assert watched is not None
    zone, feed = watched
    feed(_Arm(world.q_home_rad))
    feed.start()
    try:
        deadline = time.monotonic() + 20
        while zone.images < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        feed.close()
    assert zone.images >= 3 and not feed.errors, feed.errors
    occupied = zone.map.occupied_centres()
    assert len(occupied) > 0
    # the box's top: 2.3 m camera height - 1.0 m (the flat image also reaches past the
    # table's edges, where a plane at the table's height is not the cell file's)
    assert np.count_nonzero(np.abs(occupied[:, 2] - 1.3) < 0.03) > 20


def test_a_bad_depth_source_is_a_usage_error(tmp_path):
    camera = load_cell(CELL).cell.cameras["overhead"]
    with pytest.raises(UsageError, match="give twin, replay:DIR, or MODULE:FACTORY"):
        depth_source("nonsense", "overhead", camera, None)
    with pytest.raises(UsageError, match="cannot load it"):
        depth_source("no_such_module:make", "overhead", camera, None)
    with pytest.raises(UsageError, match=r"no \*\.npy files"):
        depth_source(f"replay:{tmp_path}", "overhead", camera, None).connect()


def test_run_on_the_virtual_controller_is_watched_by_the_twins_depth_camera():
    host = "127.0.0.152"
    with twin(CELL, host):
        done = cli(
            "run", str(CELL), str(ROOT / "tasks" / "home.yaml"), "--backend", "ur",
            "--robot-host", host, "--json",
        )  # fmt: skip
    result = json.loads(done.stdout)
    assert result["result_code"] == 0, done.stderr[-2000:]
    assert result["depth_images"] > 0 and result["obstacles"] == []
