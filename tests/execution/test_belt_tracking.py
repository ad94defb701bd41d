"""Running a tracked pick on the twin's moving belt (SPEC section 13): the belt carries
its parts by friction and its encoder and photo-eye reach the engine; a belt above its
speed_max lets the part go (109); a belt that stops while the arm follows it is a
controlled stop (100), not a chase."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from cellrunner.backends.factory import make_backend
from cellrunner.cli.common import console
from cellrunner.execution.rehearsal import RehearsedJob, start_rehearsal
from cellrunner.model.codes import ResultCode
from cellrunner.model.job_steps import job_steps
from cellrunner.model.load import load_cell, load_task
from tests.conftest import ROOT

CELL = ROOT / "cells" / "conveyor_pick_ur10e.yaml"
TASK = ROOT / "tasks" / "conveyor_pick.yaml"


def _rehearse(belt_mps: float | None = None, observer: Any = None) -> tuple[RehearsedJob, Any]:
    """One job of the reference task on the twin; the caller closes the rehearsal."""
    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=[{}])
    rehearsal = start_rehearsal(cell, task, backend, console())
    if belt_mps is not None:
        backend.set_belt_speed("belt", belt_mps)
    if observer is not None:
        rehearsal.loop.add_observer(observer)
    try:
        return rehearsal.rehearse({}, job_steps(task, cell.cell, {})), rehearsal
    except BaseException:
        rehearsal.close()
        raise


def test_the_belt_carries_the_part_by_friction_past_the_eye():
    """No teleporting: the block, spawned at rest upstream of the eye, is dragged up to
    the belt's speed and rides it; the eye's input rises when it crosses; the encoder
    counts whole ticks of the belt's travel."""
    from cellrunner.sim.from_cell import description_of

    backend = make_backend(load_cell(CELL), "sim")
    backend.connect()
    try:
        world = backend.world
        assert world is not None
        desc = description_of(load_cell(CELL))
        (eye,) = [s for s in desc.presence_sensors if s.channel == "DI0"]
        y0 = float(world.part_pose_world("block")[1, 3])
        seen_at = None
        for _ in range(1000):  # 2 s
            backend.wait_period()
            state = backend.read_state()
            if seen_at is None and state.inputs.get("DI0"):
                seen_at = float(world.part_pose_world("block")[1, 3])
        v = world.part_velocity_world("block")
        travel = backend.conveyor_travel_m("belt")
        assert travel is not None and abs(travel * 4000 - round(travel * 4000)) < 1e-6
        assert travel == pytest.approx(0.6, abs=0.002)  # 2 s at speed_max 0.3 m/s
        assert float(v[1]) == pytest.approx(0.3, abs=0.005) and abs(float(v[2])) < 0.01
        y1 = float(world.part_pose_world("block")[1, 3])
        assert 0.58 < y1 - y0 < 0.6  # a little slip while it was dragged up to speed
        assert seen_at is not None and abs(seen_at - eye.center_world_m[1]) < 0.002
    finally:
        backend.close()


def test_a_belt_above_its_speed_max_lets_the_part_go_with_109():
    job, rehearsal = _rehearse(belt_mps=0.6)
    try:
        assert job.code is ResultCode.PART_LEFT_WINDOW, job.payload["result_text"]
        assert "the belt runs at 0.6" in job.payload["result_text"]
        assert "above its speed_max 0.3 m/s" in job.payload["result_text"]
        world = rehearsal.backend.world
        # the arm never went for it: the block rides on at the belt's speed, on the belt
        assert float(world.part_velocity_world("block")[1]) == pytest.approx(0.6, abs=0.01)
        assert float(world.part_pose_world("block")[2, 3]) == pytest.approx(0.827, abs=0.002)
        assert np.linalg.norm(world.tcp_pose_world()[:3, 3] - [0.75, 0.0, 0.95]) < 0.01
    finally:
        rehearsal.close()


def test_a_part_latched_before_the_job_and_past_the_latest_start_ends_109():
    """The block crosses the eye while the cell stands idle (the engine latches it between
    jobs); by the time the arm is over the belt it is past the latest start the window
    allows at 0.3 m/s (-0.031 m): the part is let go, the arm does not go for it."""
    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=[{}])
    rehearsal = start_rehearsal(cell, task, backend, console())
    try:
        rehearsal.loop.step(750)  # 1.5 s idle: the block passes the eye (at 0.83 s)
        job = rehearsal.rehearse({}, job_steps(task, cell.cell, {}))
        assert job.code is ResultCode.PART_LEFT_WINDOW, job.payload["result_text"]
        assert "must start by -0.03" in job.payload["result_text"]
        world = backend.world
        assert float(world.part_velocity_world("block")[1]) == pytest.approx(0.3, abs=0.01)
        assert np.linalg.norm(world.tcp_pose_world()[:3, 3] - [0.75, 0.0, 0.95]) < 0.01
    finally:
        rehearsal.close()


class _Follows:
    """Acts once the arm follows the block (the TCP within 5 cm of it seen from above and
    moving along the belt faster than 0.25 m/s); remembers when."""

    def __init__(self, act: Any) -> None:
        self.act = act
        self.acted_at_s: float | None = None
        self.last: tuple[float, float] | None = None

    def __call__(self, cell: Any) -> None:
        world = cell.backend.world
        if self.acted_at_s is not None or world is None:
            return
        tcp = world.tcp_pose_world()[:2, 3]
        part = world.part_pose_world("block")[:2, 3]
        last, self.last = self.last, (world.time_s, float(tcp[1]))
        if last is None or world.time_s <= last[0]:
            return
        vy = (float(tcp[1]) - last[1]) / (world.time_s - last[0])
        if np.linalg.norm(tcp - part) < 0.05 and vy > 0.25:
            self.act(cell.backend)
            self.acted_at_s = world.time_s


def test_an_encoder_jump_while_following_is_a_controlled_stop():
    jump = _Follows(lambda backend: backend.jump_belt_encoder("belt", 0.05))
    job, rehearsal = _rehearse(observer=jump)
    try:
        assert jump.acted_at_s is not None
        assert job.code is ResultCode.PROTECTIVE_STOP, job.payload["result_text"]
        # the 50 mm jump and the belt's travel over the period it came in
        text = job.payload["result_text"]
        assert re.search(r"belt is \+50\.\d mm off its measured 0\.300 m/s", text), text
        world = rehearsal.backend.world
        rehearsal.loop.step(250)  # 0.5 s: the stop ramp ends
        assert float(np.abs(world.measure().qd_rad_s).max()) < 1e-2
        # the arm did not chase the reading 5 cm on: it stopped, the block rode on
        assert float(world.part_pose_world("block")[1, 3]) > float(world.tcp_pose_world()[1, 3])
    finally:
        rehearsal.close()


def test_a_belt_that_stops_mid_pick_is_a_controlled_stop_not_a_chase():
    stop = _Follows(lambda backend: backend.set_belt_speed("belt", 0.0))
    job, rehearsal = _rehearse(observer=stop)
    try:
        assert stop.acted_at_s is not None
        assert job.code is ResultCode.PROTECTIVE_STOP, job.payload["result_text"]
        assert "controlled stop" in job.payload["result_text"]
        assert "off its measured 0.300 m/s" in job.payload["result_text"]
        world = rehearsal.backend.world
        rehearsal.loop.step(250)  # 0.5 s: the stop ramps end
        # the belt, the block and the arm stand; the arm stopped over the block, it did
        # not go on along the belt
        assert abs(float(world.part_velocity_world("block")[1])) < 0.01
        assert float(np.abs(world.measure().qd_rad_s).max()) < 1e-2
        tcp_y = float(world.tcp_pose_world()[1, 3])
        assert abs(tcp_y - float(world.part_pose_world("block")[1, 3])) < 0.02
    finally:
        rehearsal.close()
