"""Faults happen physically and show up only through sensors and the safety state."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cellrunner.errors import BackendError
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.sim import demo
from cellrunner.sim.safety import UNLOCK_DELAY_S


def _no_fault_fields(state: RobotState) -> None:
    names = {f.name for f in dataclasses.fields(state)}
    assert not any("fault" in n or "inject" in n for n in names)


def test_grip_miss_moves_the_part_away_and_the_jaws_close_on_nothing(driver) -> None:
    b = driver.backend
    b.inject_fault("grip_miss")
    state = b.read_state()
    _no_fault_fields(state)
    assert state.safety is Safety.NORMAL  # nothing visible before the jaws close
    driver.pick_cube()
    state = b.read_state()
    assert state.inputs["DI0"] is False
    assert b.world.jaw_gap_m() < 0.002
    cube = b.world.part_pose_world("cube")[:3, 3]
    assert np.linalg.norm(cube[:2] - np.array(demo.CUBE_XYZ_M[:2])) > 0.1
    assert cube[2] == pytest.approx(demo.CUBE_XYZ_M[2], abs=0.003)  # still on the table
    # lifting weighs nothing
    b.zero_ft_sensor()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.2), 1.0)
    driver.wait(0.2)
    assert abs(b.read_state().wrench_N[2]) < 0.3
    # the fault fires once: a retry at the part's new place grips it
    driver.backend.set_output("DO0", False)
    driver.wait(0.6)
    driver.move_tcp(cube + (0, 0, 0.105), 1.5)
    driver.move_tcp(cube + (0, 0, 0.005), 0.8)
    b.set_output("DO0", True)
    driver.wait(0.6)
    assert b.read_state().inputs["DI0"] is True


def test_part_slip_drops_the_part_in_transit(driver) -> None:
    b = driver.backend
    driver.pick_cube()
    b.zero_ft_sensor()
    b.inject_fault("part_slip")  # armed: fires once the gripped part is in the air
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.2), 1.0, "lift")
    driver.move_tcp((0.40, 0.10, 1.10), 1.5, "transfer")
    driver.wait(0.5)
    state = b.read_state()
    assert abs(state.wrench_N[2]) < 0.3  # the weight is gone
    assert state.inputs["DI0"] is False  # jaws closed past the part
    assert b.world.part_pose_world("cube")[2, 3] < 0.96  # it fell to the table
    # friction is back to normal once the part left the fingers
    cube = b.world.model.geom("part:cube").id
    assert b.world.model.geom_friction[cube, 0] == pytest.approx(0.8)


def test_part_slip_while_carrying_drops_it_at_once(driver) -> None:
    b = driver.backend
    driver.pick_cube()
    b.zero_ft_sensor()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.2), 1.0, "lift")
    driver.wait(0.1)
    assert b.read_state().wrench_N[2] < -2.5
    b.inject_fault("part_slip")
    driver.wait(0.4)
    assert abs(b.read_state().wrench_N[2]) < 0.3


def test_arm_pushed_into_a_fixture_raises_a_protective_stop_and_holds(driver) -> None:
    b = driver.backend
    driver.move_tcp((0.30, 0.20, 1.00), 2.0)
    with pytest.raises(BackendError, match="safety state is protective_stop"):
        driver.move_tcp((0.30, 0.20, 0.85), 1.5)  # pads would go 5 cm into the table
    state = b.read_state()
    assert state.safety is Safety.PROTECTIVE_STOP
    assert b.world.last_contact is not None
    assert "fixture:table" in b.world.last_contact.geoms
    driver.wait(0.5)
    state = b.read_state()
    assert np.abs(state.qd_rad_s).max() < 1e-3  # standing still
    assert b.world.tcp_pose_world()[2, 3] > 0.915  # stopped at the table, not through it
    with pytest.raises(BackendError, match="unlocked yet"):
        b.unlock_protective_stop()


def test_protective_stop_unlock_waits_five_simulated_seconds(driver) -> None:
    b = driver.backend
    driver.move_tcp((0.35, 0.1, 1.2), 1.0)
    b.inject_fault("protective_stop")
    t_stop = b.sim_time_s
    assert b.read_state().safety is Safety.PROTECTIVE_STOP
    driver.wait(UNLOCK_DELAY_S - 0.1)
    with pytest.raises(
        BackendError,
        match=r"protective stop cannot be unlocked yet: 4.90 s since "
        r"the stop, the controller needs 5 s",
    ):
        b.unlock_protective_stop()
    driver.wait(0.1)
    assert b.sim_time_s - t_stop >= UNLOCK_DELAY_S
    b.unlock_protective_stop()
    assert b.read_state().safety is Safety.NORMAL
    driver.q = b.read_state().q_rad
    driver.move_tcp((0.45, -0.1, 1.15), 1.0)  # moves again


def test_protective_stop_mid_motion_decelerates_to_standstill(driver) -> None:
    b = driver.backend
    rate = b.rate_hz
    q_to = demo.solve_ik(driver.desc, demo.tcp_down_at((0.3, 0.3, 1.1)), driver.q)
    from cellrunner.model.trajectory import approve

    approved = approve(
        demo.to_trajectory(demo.quintic_blend(driver.q, q_to, 2.0, rate), rate), 0, "move"
    )
    for i in range(500):  # half way, full speed
        b.servo(approved, i)
        b.wait_period()
    assert np.abs(b.read_state().qd_rad_s).max() > 0.5
    b.inject_fault("protective_stop")
    with pytest.raises(BackendError):
        b.servo(approved, 500)
    driver.wait(0.3)
    assert np.abs(b.read_state().qd_rad_s).max() < 1e-3


def test_estop_powers_off_and_needs_release_before_recovery(driver) -> None:
    b = driver.backend
    driver.move_tcp((0.35, 0.1, 1.2), 1.0)
    b.inject_fault("estop")
    driver.wait(0.3)
    state = b.read_state()
    assert state.safety is Safety.EMERGENCY_STOP
    assert state.powered is False and state.brakes_released is False
    with pytest.raises(BackendError, match="still pressed"):
        b.recover_from_estop()
    with pytest.raises(BackendError, match="emergency_stop"):
        b.unlock_protective_stop()
    b.release_estop()
    assert b.read_state().safety is Safety.EMERGENCY_STOP  # released is not recovered
    b.recover_from_estop()
    state = b.read_state()
    assert state.safety is Safety.NORMAL and state.powered is True
    driver.q = state.q_rad
    driver.move_tcp((0.45, -0.1, 1.15), 1.0)


def test_robot_disconnect_reports_disconnected_until_reconnected(driver) -> None:
    b = driver.backend
    driver.move_tcp((0.35, 0.1, 1.2), 1.0)
    b.inject_fault("robot_disconnect")
    state = b.read_state()
    assert state.safety is Safety.DISCONNECTED
    with pytest.raises(BackendError, match="robot connection lost"):
        b.set_output("DO0", True)
    t = b.sim_time_s
    b.wait_period()  # the world goes on
    assert b.read_state().time_s > t
    b.connect()
    assert b.read_state().safety is Safety.NORMAL


def test_unknown_fault_lists_the_known_ones(backend) -> None:
    with pytest.raises(
        ValueError,
        match=r"unknown fault 'gremlins'; known: grip_miss, part_slip, "
        r"protective_stop, estop, robot_disconnect",
    ):
        backend.inject_fault("gremlins")


def test_presence_sensor_sees_the_part_leave(cell) -> None:
    from conftest import Driver

    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.sim.description import PresenceSensor

    desc = dataclasses.replace(
        cell, presence_sensors=(PresenceSensor("DI2", demo.CUBE_XYZ_M, (0.04, 0.04, 0.04)),)
    )
    b = SimBackend(desc)
    b.connect()
    assert b.read_state().inputs["DI2"] is True
    with pytest.raises(BackendError, match="driven by a twin sensor"):
        b.set_input("DI2", False)
    b.inject_fault("grip_miss")
    Driver(b, desc).pick_cube()  # the miss pushes the cube out of the barrier
    assert b.read_state().inputs["DI2"] is False


def test_a_contact_is_a_collision_over_a_few_periods_not_one() -> None:
    """As the controller filters its force estimate: a single period of a stiff contact
    over the 60 N limit (the flake of the guarded move through ur_rtde) is no collision;
    a contact that stays over it, or one three times as hard, is."""
    from cellrunner.sim.contacts import collided

    recent: list[float] = []
    assert not collided(recent, 95.0, 60.0)  # one period's spike
    assert not collided(recent, 20.0, 60.0)
    assert not collided(recent, 20.0, 60.0)
    assert [collided(recent, f, 60.0) for f in (70.0, 75.0, 80.0)] == [False, False, True]
    assert collided([], 190.0, 60.0)  # a hard hit stops at once
