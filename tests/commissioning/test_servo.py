"""The servo tick on the cell's own kinematics and collision model (no robot): timeout,
dead band, jerk-limited smoothing that keeps a straight line straight, speed caps."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.commissioning import jog, servo
from cellrunner.commissioning.servo import Command, Servo
from tests.commissioning.conftest import write_project

HOME = np.radians([0, -90, 90, -90, -90, 0])


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    cell, _ = write_project(tmp_path_factory.mktemp("servo"))
    return CellWorld(load_cell(cell))


def run(world, command_at, seconds: float, q0=HOME):
    """Ticks for ``seconds`` integrating the joint speeds (an ideal arm); ``command_at(t)``
    is the command standing at t. The TCP positions (world) and joint speeds per tick."""
    s = Servo(world)
    q, dt = q0.copy(), s.period_s
    tcp, speeds = [], []
    for i in range(int(seconds / dt)):
        t = i * dt
        tick = s.step(q, command_at(t), t)
        q = q + tick.qd_rad_s * dt
        tcp.append(world.kinematics.p_world_tcp(q))
        speeds.append(tick.qd_rad_s)
    return np.array(tcp), np.array(speeds)


def test_a_twist_is_followed_on_a_straight_line_and_stops_after_the_timeout(world):
    v = (0.1, 0.0, 0.0, 0.0, 0.0, 0.0)
    tcp, qd = run(world, lambda t: Command("base", v, t) if t < 1.0 else None, 1.5)
    R = world.kinematics.T_world_base[:3, :3]
    direction = R @ np.array([1.0, 0, 0])
    d = tcp - tcp[0]
    along = d @ direction
    off_line = np.linalg.norm(d - np.outer(along, direction), axis=1)
    assert off_line.max() < 0.5e-3, off_line.max()
    assert 0.09 < along[int(1.0 / 0.002)] < 0.1, "0.1 m/s for 1 s, less the ramp"
    # the last command stands for TIMEOUT_S, then the arm brakes to a stop
    stop_tick = int((1.0 + servo.TIMEOUT_S) / 0.002) + int(0.2 / 0.002)
    assert np.all(qd[stop_tick:] == 0)


def test_the_ramp_is_jerk_limited(world):
    v = (0.0, 0.0, -0.2, 0.0, 0.0, 0.0)
    tcp, _ = run(world, lambda t: Command("base", v, t), 0.5)
    speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) / 0.002
    accel = np.diff(speed) / 0.002
    assert speed[0] < 0.001, "no step in speed"
    assert accel.max() < servo.LINEAR_ACCEL_MPS2 * 1.05
    assert abs(speed[-1] - 0.2) < 0.002


def test_old_commands_the_dead_band_and_the_cap(world):
    s = Servo(world)
    stale = Command("base", (0.05, 0, 0, 0, 0, 0), -servo.TIMEOUT_S - 0.01)
    assert not s.step(HOME, stale, 0.0).commanded
    tiny = Command("base", (servo.DEAD_BAND_MPS / 2, 0, 0, 0, 0, 0), 0.0)
    tick = s.step(HOME, tiny, 0.0)
    assert tick.commanded and tick.verdict is None and not np.any(tick.qd_rad_s)
    fast = Command("joint", (1.0, 0.5, 0, 0, 0, 0), 0.0).capped()
    assert fast.velocity[0] == pytest.approx(np.radians(jog.JOINT_SPEED_DEG_S))
    assert fast.velocity[1] == pytest.approx(fast.velocity[0] / 2), "direction kept"


def test_a_change_of_frame_brakes_first(world):
    s = Servo(world)
    for i in range(100):
        s.step(HOME, Command("base", (0.05, 0, 0, 0, 0, 0), i * 0.002), i * 0.002)
    tick = s.step(HOME, Command("joint", (0, 0, 0, 0, 0, 0.2), 0.2), 0.2)
    assert tick.frame == "base", "still braking in the old frame"
    for i in range(101, 400):
        tick = s.step(HOME, Command("joint", (0, 0, 0, 0, 0, 0.2), i * 0.002), i * 0.002)
    assert tick.frame == "joint" and tick.qd_rad_s[5] > 0.19


def test_the_governor_holds_a_joint_at_its_limit(tmp_path):
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld
    from tests.commissioning.conftest import CELL

    cell, _ = write_project(
        tmp_path,
        cell=CELL.replace(
            "  home: [0, -90, 90, -90, -90, 0]\n",
            "  home: [0, -90, 90, -90, -90, 0]\n  joint_range: [[-360, 360], [-360, 360], [-360, 360], [-360, 360], [-360, 360], [-30, 30]]\n",
        ),
    )
    world = CellWorld(load_cell(cell))
    g = jog.Governor(world.kinematics, world.collision)
    q = HOME.copy()
    toward = np.array([0, 0, 0, 0, 0, 0.1])
    q[5] = np.radians(10)
    assert g.judge(q, toward).scale == 1.0
    q[5] = np.radians(25)
    slowing = g.judge(q, toward)
    assert 0 < slowing.scale < 1 and slowing.reason.startswith("joint 6 limit")
    q[5] = np.radians(29)
    assert g.judge(q, toward).scale == 0.0
    assert g.judge(q, -toward).scale == 1.0


class Wall:
    """A watched-zone map with one occupied voxel plane at world x = 0.9."""

    def __init__(self, world):
        self.world = world

    def clearance_m(self, q):
        return 0.9 - float(self.world.kinematics.p_world_tcp(q)[0]), "voxel at x 0.90 m"


def test_the_watched_zone_slows_and_stops_the_arm(world):
    g = jog.Governor(world.kinematics, world.collision, obstacles=Wall(world))
    s = Servo(world, governor=g)
    q, dt = HOME.copy(), s.period_s
    reasons = set()
    for i in range(int(6.0 / dt)):
        tick = s.step(q, Command("base", (-0.1, 0, 0, 0, 0, 0), i * dt), i * dt)
        q = q + tick.qd_rad_s * dt
        if tick.verdict and tick.verdict.reason:
            reasons.add(tick.verdict.reason.split(" at ")[0])
    x = world.kinematics.p_world_tcp(q)[0]
    assert 0.9 - jog.CLEARANCE_SLOW_M < x < 0.9 - 0.005, x
    assert "watched zone: voxel" in reasons
