"""The jog's velocity mapping and its governor, on the cell's own kinematics and
collision model (no robot)."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.commissioning import jog
from tests.commissioning.conftest import write_project

HOME = np.radians([0, -90, 90, -90, -90, 0])


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    cell, _ = write_project(tmp_path_factory.mktemp("jog"))
    return CellWorld(load_cell(cell))


@pytest.mark.parametrize("mode", ["base", "tool"])
@pytest.mark.parametrize("axis", range(6))
def test_cartesian_jog_moves_the_tcp_along_the_asked_axis(world, mode, axis):
    k = world.kinematics
    qd = jog.requested_qd(k, HOME, mode, axis, +1, 0.5)
    dt = 1e-4
    T0, T1 = k.T_world_tcp(HOME), k.T_world_tcp(HOME + qd * dt)
    R = k.T_world_base[:3, :3] if mode == "base" else T0[:3, :3]
    v = R.T @ (T1[:3, 3] - T0[:3, 3]) / dt
    dR = T1[:3, :3] @ T0[:3, :3].T
    w = R.T @ np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / (2 * dt)
    twist = np.concatenate([v, w])
    expected = np.zeros(6)
    expected[axis] = 0.5 * (
        jog.LINEAR_SPEED_MPS if axis < 3 else np.radians(jog.ANGULAR_SPEED_DEG_S)
    )
    assert np.allclose(twist, expected, atol=0.02 * abs(expected[axis]))


def test_wrist_singularity_slows_then_stops_and_lets_the_arm_back_out(world):
    g = jog.Governor(world.kinematics, world.collision)
    toward = lambda q: jog.requested_qd(world.kinematics, q, "joint", 4, +1, 1.0)  # noqa: E731
    q = HOME.copy()
    q[4] = np.radians(-30)
    assert g.judge(q, toward(q)).scale == 1.0
    q[4] = np.radians(-14)
    slowing = g.judge(q, toward(q))
    assert 0 < slowing.scale < 1 and slowing.reason.startswith("wrist singularity")
    q[4] = np.radians(-jog.WRIST_STOP_DEG - 1)
    assert g.judge(q, toward(q)).scale == 0.0
    assert g.judge(q, -toward(q)).scale == 1.0, "away from it is never held back"


def test_the_dead_man_drops_the_key_when_repeats_stop():
    d = jog.DeadMan()
    d.press("a", 0.0)
    assert d.held(jog.DEADMAN_FIRST_S - 0.01) == "a"  # before the terminal starts repeating
    d.press("a", 0.5)
    d.press("a", 0.53)
    assert d.held(0.53 + jog.DEADMAN_S - 0.01) == "a"
    assert d.held(0.53 + jog.DEADMAN_S + 0.01) is None
