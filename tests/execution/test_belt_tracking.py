"""Running a tracked pick on the twin's moving belt (SPEC section 13): the belt carries
its parts by friction and its encoder and photo-eye reach the engine; a belt above its
speed_max lets the part go (109); a belt that stops while the arm follows it is a
controlled stop (100), not a chase; one that ramps down and up again as a line's drive does
holds the arm with it."""

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
        # the 50 mm jump, within the encoder's quarter-mm ticks
        text = job.payload["result_text"]
        found = re.search(r"belt is \+(\d+\.\d) mm off its measured 0\.300 m/s", text)
        assert found is not None and 49.5 <= float(found.group(1)) <= 50.9, text
        world = rehearsal.backend.world
        rehearsal.loop.step(250)  # 0.5 s: the stop ramp ends
        assert float(np.abs(world.measure().qd_rad_s).max()) < 1e-2
        # the arm did not chase the reading 5 cm on: it stopped, the block rode on
        assert float(world.part_pose_world("block")[1, 3]) > float(world.tcp_pose_world()[1, 3])
    finally:
        rehearsal.close()


def test_a_belt_stopped_at_once_mid_pick_is_a_controlled_stop_not_a_chase():
    """The belt stands within a few ms (no drive ramps that fast): the arm cannot stop
    with it within its limits, it stops where it is and ends 100."""
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


class _StopAndGo:
    """Once the arm follows the block: the line's drive ramps the belt down to a stand at
    ``ramp`` m/s^2, keeps it still ``stand_s``, ramps it up again; meanwhile the TCP's
    distance to the block along the belt is sampled every period."""

    def __init__(self, ramp: float, stand_s: float) -> None:
        self.follows = _Follows(lambda backend: backend.set_belt_speed("belt", 0.0, ramp))
        self.ramp, self.stand_s = ramp, stand_s
        self.restarted_at_s: float | None = None
        self.standing: list[tuple[float, float, float]] = []  # (t, tcp - block along y, tcp vy)

    def __call__(self, cell: Any) -> None:
        self.follows(cell)
        world = cell.backend.world
        t0 = self.follows.acted_at_s
        if t0 is None or world is None:
            return
        still_from = t0 + 0.3 / self.ramp
        if still_from + 0.1 < world.time_s < t0 + 0.3 / self.ramp + self.stand_s:
            gap = float(world.tcp_pose_world()[1, 3] - world.part_pose_world("block")[1, 3])
            vy = float(np.linalg.norm(world.measure().qd_rad_s))
            self.standing.append((world.time_s, gap, vy))
        if self.restarted_at_s is None and world.time_s >= still_from + self.stand_s:
            cell.backend.set_belt_speed("belt", 0.3, self.ramp)
            self.restarted_at_s = world.time_s


def test_a_belt_that_stops_mid_pick_along_its_drive_ramp_holds_the_arm_with_it():
    """The belt ramps down at 2 m/s^2 while the arm follows the block, stands 1 s and
    ramps up again: the arm slows, stands and goes on with it, the pick ends 0 with the
    block in the tray, no controlled stop."""
    go = _StopAndGo(ramp=2.0, stand_s=1.0)
    job, rehearsal = _rehearse(observer=go)
    try:
        assert go.follows.acted_at_s is not None and go.restarted_at_s is not None
        assert job.code is ResultCode.OK, job.payload["result_text"]
        assert len(go.standing) > 300  # sampled through most of the stand
        # while the belt stood the arm stood with the block under it, where it was
        assert max(abs(vy) for _, _, vy in go.standing) < 0.02
        gaps = [gap for _, gap, _ in go.standing]
        assert max(gaps) - min(gaps) < 0.001
        assert max(abs(g) for g in gaps) < 0.01
        world = rehearsal.backend.world
        block = world.part_pose_world("block")[:3, 3]
        assert np.linalg.norm(block[:2] - [0.35, 0.55]) < 0.01  # in the tray (tray_slot)
    finally:
        rehearsal.close()


class _StopBeforeStart:
    """Once the block is past the eye and the arm still waits over the frame: the belt
    ramps down, stands ``stand_s`` and ramps up again (at ``ramp`` m/s^2)."""

    def __init__(self, ramp: float, stand_s: float) -> None:
        self.ramp, self.stand_s = ramp, stand_s
        self.stopped_at_s: float | None = None
        self.restarted_at_s: float | None = None
        self.tcp_while_standing: list[np.ndarray] = []

    def __call__(self, cell: Any) -> None:
        world = cell.backend.world
        if world is None:
            return
        if self.stopped_at_s is None:
            over_frame = np.linalg.norm(world.tcp_pose_world()[:3, 3] - [0.75, 0.0, 0.95])
            if over_frame < 0.002 and float(world.part_pose_world("block")[1, 3]) > -0.40:
                cell.backend.set_belt_speed("belt", 0.0, self.ramp)
                self.stopped_at_s = world.time_s
            return
        still_from = self.stopped_at_s + 0.3 / self.ramp
        if still_from < world.time_s < still_from + self.stand_s:
            self.tcp_while_standing.append(world.tcp_pose_world()[:3, 3].copy())
        if self.restarted_at_s is None and world.time_s >= still_from + self.stand_s:
            cell.backend.set_belt_speed("belt", 0.3, self.ramp)
            self.restarted_at_s = world.time_s


def test_a_belt_that_stops_before_the_arm_goes_onto_it_is_waited_for():
    """The belt stands 1 s between the eye and the window while the arm waits over the
    frame: the arm keeps waiting (it does not go for a part that does not come), and
    picks the block when the belt brings it; the job ends 0."""
    wait = _StopBeforeStart(ramp=2.0, stand_s=1.0)
    job, rehearsal = _rehearse(observer=wait)
    try:
        assert wait.stopped_at_s is not None and wait.restarted_at_s is not None
        assert job.code is ResultCode.OK, job.payload["result_text"]
        assert len(wait.tcp_while_standing) > 400
        # the arm stood over the frame (above_belt) all the while the belt stood
        for tcp in wait.tcp_while_standing:
            assert np.linalg.norm(tcp - [0.75, 0.0, 0.95]) < 0.002
        block = rehearsal.backend.world.part_pose_world("block")[:3, 3]
        assert np.linalg.norm(block[:2] - [0.35, 0.55]) < 0.01
    finally:
        rehearsal.close()


class _StandThenRun:
    """The belt stands (ramped down) before the arm reaches the frame, so the pick is made
    for a standing part; it starts again while the arm comes down on the block."""

    def __init__(self) -> None:
        self.stopped = False
        self.restarted = False

    def __call__(self, cell: Any) -> None:
        world = cell.backend.world
        if world is None:
            return
        if not self.stopped and float(world.part_pose_world("block")[1, 3]) > -0.45:
            cell.backend.set_belt_speed("belt", 0.0, 2.0)
            self.stopped = True
        tcp = world.tcp_pose_world()[:3, 3]
        if self.stopped and not self.restarted and float(tcp[1]) < -0.3 and tcp[2] < 0.9:
            cell.backend.set_belt_speed("belt", 0.3, 2.0)
            self.restarted = True


def test_a_standing_belt_that_starts_again_mid_pick_is_a_controlled_stop():
    """Picked as a standing part (an indexing belt), the block starts to move away under
    the jaws: the arm does not follow a plan made for a still part; 100."""
    run = _StandThenRun()
    job, rehearsal = _rehearse(observer=run)
    try:
        assert run.stopped and run.restarted
        assert job.code is ResultCode.PROTECTIVE_STOP, job.payload["result_text"]
        assert "measured 0.000 m/s" in job.payload["result_text"]
    finally:
        rehearsal.close()


def test_a_belt_that_stays_stopped_under_a_pick_ends_with_the_step_timeout():
    """Ramped down while the arm follows the block and never started again: the arm stands
    with it until the step's timeout (60 s of the twin's time), then the job ends 105, the
    arm standing over the block."""
    go = _StopAndGo(ramp=2.0, stand_s=1e9)
    job, rehearsal = _rehearse(observer=go)
    try:
        assert go.follows.acted_at_s is not None and go.restarted_at_s is None
        assert job.code is ResultCode.STEP_TIMEOUT, job.payload["result_text"]
        # the step's own timeout (60 s from the track step's start) comes first
        assert "track 'belt' timed out" in job.payload["result_text"]
        # the arm stood over the block all the while
        gaps = [gap for _, gap, _ in go.standing]
        assert max(gaps) - min(gaps) < 0.001
    finally:
        rehearsal.close()
