"""SimBackend as the engine sees it: tracking, refusals, IO, the gripper and the wrist."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.backends.base import RobotBackend
from cellrunner.backends.sim.backend import SimBackend
from cellrunner.errors import BackendError
from cellrunner.model.robot_state import Safety
from cellrunner.model.trajectory import ApprovedTrajectory, approve
from cellrunner.sim import demo

GRAVITY = 9.81


def test_sim_backend_implements_the_protocol(backend: SimBackend) -> None:
    from tests.protocol_check import assert_implements

    assert_implements(backend, RobotBackend)
    assert backend.rate_hz == 500.0


def test_constructor_does_no_work_and_connect_builds(cell) -> None:
    b = SimBackend(cell)
    assert b.world is None
    with pytest.raises(BackendError, match="not connected"):
        b.read_state()
    b.connect()
    assert b.read_state().safety is Safety.NORMAL
    b.close()
    b.close()  # idempotent


def test_pick_place_motion_is_tracked_within_a_millimetre(driver) -> None:
    cube = np.array(demo.CUBE_XYZ_M)
    driver.move_tcp(cube + (0, 0, 0.105), 2.0, "approach")
    driver.move_tcp(cube + (0, 0, 0.005), 0.8, "descend")
    driver.move_tcp(cube + (0, 0, 0.2), 0.8, "lift")
    driver.move_tcp((0.40, 0.30, 1.05), 1.6, "transfer")
    driver.move_joints(np.array(driver.desc.q_home_rad), 1.8, "home")
    assert max(driver.errors_m) < 1e-3, driver.errors_m  # spec: < 5 mm
    # and the motion was real: the TCP went where it was told
    np.testing.assert_allclose(
        driver.backend.world.tcp_pose_world()[:3, 3],
        driver.tcp_of(np.array(driver.desc.q_home_rad)),
        atol=1e-3,
    )


def test_sim_clock_advances_one_period_per_wait(backend: SimBackend) -> None:
    for _ in range(250):
        backend.wait_period()
    assert backend.sim_time_s == pytest.approx(0.5, abs=1e-9)
    assert backend.read_state().time_s == pytest.approx(0.5, abs=1e-9)


def test_unsealed_and_forged_trajectories_are_refused(backend: SimBackend, cell) -> None:
    q = np.array(cell.q_home_rad)
    traj = demo.to_trajectory(np.vstack([q, q]), backend.rate_hz)
    with pytest.raises(BackendError, match="unsealed trajectory"):
        backend.servo(ApprovedTrajectory(traj, 0, "forged"), 0)
    with pytest.raises(BackendError, match="unsealed trajectory"):
        backend.servo(ApprovedTrajectory(traj, 0, "forged", "0" * 64), 0)
    backend.servo(approve(traj, 0, "ok"), 0)  # the sealed one goes through


def test_set_point_jumps_beyond_the_speed_limit_are_refused(backend: SimBackend, cell) -> None:
    q = np.array(cell.q_home_rad)
    far = q + np.radians([0, 0, 5, 0, 0, 0])
    jumpy = approve(demo.to_trajectory(np.vstack([q, far]), backend.rate_hz), 3, "jumpy")
    with pytest.raises(
        BackendError,
        match=r"set-point 1 of step 3 \(jumpy\) jumps 5.00 deg on "
        r"joint 3 in one period; the joint speed limit allows "
        r"0.54 deg",
    ):
        backend.servo(jumpy, 0)
    # a smooth trajectory that starts away from where the arm is
    elsewhere = approve(demo.to_trajectory(np.vstack([far, far]), backend.rate_hz), 4, "elsewhere")
    with pytest.raises(BackendError, match=r"set-point 0 of step 4 \(elsewhere\) jumps 5.00 deg"):
        backend.servo(elsewhere, 0)
    # skipping set-points is a jump too
    q_to = q + np.radians([0, 0, 20, 0, 0, 0])
    smooth = approve(
        demo.to_trajectory(demo.quintic_blend(q, q_to, 1.0, backend.rate_hz), backend.rate_hz),
        5,
        "smooth",
    )
    backend.servo(smooth, 0)
    backend.wait_period()
    with pytest.raises(BackendError, match=r"set-point 250 of step 5 \(smooth\) jumps"):
        backend.servo(smooth, 250)


def test_trajectory_at_the_wrong_rate_is_refused(backend: SimBackend, cell) -> None:
    q = np.array(cell.q_home_rad)
    approved = approve(demo.to_trajectory(np.vstack([q, q]), 125.0), 0, "cb3")
    with pytest.raises(BackendError, match="sampled at 125 Hz, the controller runs at 500 Hz"):
        backend.servo(approved, 0)


def test_outputs_by_channel_and_unknown_channels(backend: SimBackend) -> None:
    backend.set_output("DO3", True)
    assert backend.read_state().outputs["DO3"] is True
    with pytest.raises(BackendError, match=r"unknown output 'DO9'; known: DO0, DO1, DO2, DO3"):
        backend.set_output("DO9", True)


def test_closing_on_the_part_sets_the_sensor_and_the_wrist_weighs_it(driver) -> None:
    b = driver.backend
    assert b.read_state().inputs["DI1"] is True  # open sensor
    driver.pick_cube()
    state = b.read_state()
    assert state.inputs["DI0"] is True and state.inputs["DI1"] is False
    gap = b.world.jaw_gap_m()
    assert 0.045 < gap < 0.05  # closed on the 50 mm cube, pads pressed in slightly
    b.zero_ft_sensor()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.2), 1.0, "lift")
    driver.wait(0.2)
    state = b.read_state()
    assert state.inputs["DI0"] is True
    # UR convention: the force the environment applies to the tool, base axes
    assert state.wrench_N[2] == pytest.approx(-demo.CUBE_MASS_KG * GRAVITY, rel=0.05)
    assert np.abs(state.wrench_N[:2]).max() < 0.2
    assert b.world.part_pose_world("cube")[2, 3] > demo.CUBE_XYZ_M[2] + 0.15  # it came along


def test_closing_on_nothing_travels_to_the_end_and_the_sensor_stays_false(driver) -> None:
    b = driver.backend
    driver.move_tcp((0.30, 0.20, 1.05), 2.0)
    b.set_output("DO0", True)
    seen_true = False
    for _ in range(400):
        b.wait_period()
        seen_true |= bool(b.read_state().inputs["DI0"])
    assert not seen_true
    assert b.world.jaw_gap_m() < 0.002
    b.set_output("DO0", False)
    driver.wait(0.6)
    assert b.read_state().inputs["DI1"] is True
    assert b.world.jaw_gap_m() == pytest.approx(0.085, abs=0.002)


def test_scripted_inputs_and_sensor_inputs(backend: SimBackend) -> None:
    backend.set_input("DI2", True)
    assert backend.read_state().inputs["DI2"] is True
    with pytest.raises(BackendError, match="driven by a twin sensor"):
        backend.set_input("DI0", True)


def test_cb3_arm_at_125_hz_tracks_too() -> None:
    from conftest import Driver

    from cellrunner.model.robots import robot_spec

    desc = demo.demo_description(spec=robot_spec("ur5"), parts=())
    b = SimBackend(desc)
    b.connect()
    assert b.rate_hz == 125.0 and b.world.substeps == 4
    d = Driver(b, desc)
    d.move_tcp((0.45, -0.2, 1.1), 2.0)
    d.move_tcp((0.35, 0.3, 1.0), 2.0)
    assert max(d.errors_m) < 1e-3, d.errors_m


def test_cb3_at_125_hz_carries_a_part_through_a_brisk_lift() -> None:
    from conftest import Driver

    from cellrunner.model.robots import robot_spec

    desc = demo.demo_description(spec=robot_spec("ur5"))
    b = SimBackend(desc)
    b.connect()
    d = Driver(b, desc)
    d.pick_cube()
    assert b.read_state().inputs["DI0"] is True
    d.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.15), 0.6, "lift")
    d.move_tcp((0.40, 0.30, 1.08), 1.5, "transfer")
    cube = b.world.part_pose_world("cube")[:3, 3]
    np.testing.assert_allclose(cube, b.world.tcp_pose_world()[:3, 3] - (0, 0, 0.005), atol=0.002)
    assert max(d.errors_m) < 1e-3
