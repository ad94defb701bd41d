"""The twin's round table (SPEC section 13): a disc turning about the arc's centre carries
its parts by friction along their circle, the encoder reads the turn at the parts'
radius, and the reference round-table pick rehearses with the block ending in the tray."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cellrunner.backends.factory import make_backend
from cellrunner.cli.common import console
from cellrunner.execution.rehearsal import start_rehearsal
from cellrunner.model.codes import ResultCode
from cellrunner.model.job_steps import job_steps
from cellrunner.model.load import load_cell, load_task
from tests.conftest import ROOT

CELL = ROOT / "cells" / "round_table_ur10e.yaml"
TASK = ROOT / "tasks" / "round_table_pick.yaml"
CENTRE_XY = np.array([0.95, 0.0])  # the table's arc: radius 0.30 m, counter-clockwise
TRAY_PART_XYZ = (0.35, 0.55, 0.826)


def test_the_round_table_carries_the_part_round_its_centre_by_friction():
    backend = make_backend(load_cell(CELL), "sim")
    backend.connect()
    try:
        world = backend.world
        assert world is not None

        def angle_and_radius() -> tuple[float, float]:
            d = world.part_pose_world("block")[:2, 3] - CENTRE_XY
            return math.atan2(float(d[1]), float(d[0])), float(np.linalg.norm(d))

        a0, r0 = angle_and_radius()
        for _ in range(500):  # 1 s at speed_max 0.20 m/s
            backend.wait_period()
        a1, r1 = angle_and_radius()
        travel = backend.conveyor_travel_m("table")
        assert travel == pytest.approx(0.20, abs=0.002)
        assert abs(travel * 4000 - round(travel * 4000)) < 1e-6  # whole ticks
        # the block turned counter-clockwise about the centre, on its circle (a little
        # slip while it was dragged up to speed), and rides at the table's speed
        assert 0.18 < (a1 - a0) * 0.30 < 0.20
        assert r0 == pytest.approx(0.30, abs=0.003) and r1 == pytest.approx(0.30, abs=0.003)
        speed = float(np.linalg.norm(world.part_velocity_world("block")[:2]))
        assert speed == pytest.approx(0.20, abs=0.005)
    finally:
        backend.close()


def test_the_round_table_pick_rehearses_with_the_block_in_the_tray():
    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=[{}])
    rehearsal = start_rehearsal(cell, task, backend, console())
    try:
        job = rehearsal.rehearse({}, job_steps(task, cell.cell, {}))
        assert job.code is ResultCode.OK, job.payload["result_text"]
        placed = backend.world.part_pose_world("block")[:3, 3]
        assert np.linalg.norm(placed - TRAY_PART_XYZ) < 0.005
    finally:
        rehearsal.close()
