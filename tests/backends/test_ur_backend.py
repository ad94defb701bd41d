"""The ur backend against the virtual controller in another process, over loopback."""

from __future__ import annotations

import time

import numpy as np
import pytest

from cellrunner.backends.base import RobotBackend
from cellrunner.backends.ur import ControllerMismatch, RemoteControlOff, SafetyStop, URBackend
from cellrunner.errors import BackendError, PeerUnreachable
from cellrunner.model.robot_state import Safety
from cellrunner.model.robots import robot_spec
from cellrunner.model.trajectory import ApprovedTrajectory, Trajectory, approve
from tests.twin.twin_process import TwinProcess, fresh_host, wait_until

UR5E = robot_spec("ur5e")
Q_START = np.array([0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0])


def wave(rate_hz: float, duration_s: float, q0: np.ndarray = Q_START) -> Trajectory:
    """A smooth rest-to-rest move of every joint (cosine blend), sampled at the rate."""
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    s = 0.5 * (1 - np.cos(np.pi * t / duration_s))
    delta = np.array([0.4, -0.3, 0.25, 0.2, -0.2, 0.5])
    return Trajectory(rate_hz, t, q0 + s[:, None] * delta)


def stream(backend: URBackend, approved: ApprovedTrajectory) -> list[float]:
    """Stream every sample; the tracking error (rad, worst joint) at each cycle."""
    errors = []
    q = approved.trajectory.q_rad
    for i in range(len(q)):
        backend.servo(approved, i)
        backend.wait_period()
        errors.append(float(np.max(np.abs(backend.read_state().q_rad - q[i]))))
    return errors


def assert_tracks(errors: list[float]) -> None:
    """Tracking within a few periods of lag; bounds allow a scheduling stall on a loaded
    machine but not an arm that ignores the stream (errors of tenths of a rad)."""
    assert np.median(errors) < 0.005
    assert np.percentile(errors, 90) < 0.02
    assert max(errors) < 0.1


def test_constructor_does_no_io_and_satisfies_the_protocol():
    backend = URBackend("127.254.254.254", UR5E)  # nothing listens there
    from tests.protocol_check import assert_implements

    assert_implements(backend, RobotBackend)
    assert backend.rate_hz == 500.0
    assert backend.read_state().safety == Safety.DISCONNECTED


def test_unreachable_controller_is_peer_unreachable_quickly():
    backend = URBackend(fresh_host(), UR5E, connect_timeout_s=1.0)
    t0 = time.monotonic()
    with pytest.raises(PeerUnreachable, match="cannot reach the robot controller"):
        backend.connect()
    assert time.monotonic() - t0 < 2.0
    assert PeerUnreachable.exit_code == 3


def test_generation_mismatch_is_refused_both_ways():
    with TwinProcess("ur5") as cb3:
        with pytest.raises(ControllerMismatch, match=r"is CB3 .* ur5e is e-Series"):
            URBackend(cb3.host, UR5E).connect()
        with pytest.raises(ControllerMismatch, match="drives a UR5 but the cell's robot is ur10"):
            URBackend(cb3.host, robot_spec("ur10")).connect()
    with TwinProcess("ur5e") as eseries:
        with pytest.raises(ControllerMismatch, match=r"is e-Series .* ur5 is CB3"):
            URBackend(eseries.host, robot_spec("ur5")).connect()


def test_remote_control_off_is_refused():
    with TwinProcess("ur5e", remote_control=False) as twin:
        with pytest.raises(RemoteControlOff, match="local control"):
            URBackend(twin.host, UR5E).connect()


@pytest.fixture(scope="module")
def twin():
    with TwinProcess("ur5e") as t:
        yield t


@pytest.fixture(scope="module")
def backend(twin):
    b = URBackend(
        twin.host, UR5E, tcp_pose=(0, 0, 0.15, 0, 0, 0), payload_kg=1.2, payload_cog_m=(0, 0, 0.05)
    )
    b.connect()
    yield b
    b.close()


def test_connect_sets_tool_and_payload(backend, twin):
    state = twin.state()
    assert state["tcp_offset"][2] == pytest.approx(0.15)
    assert state["payload_kg"] == pytest.approx(1.2)


def test_connect_reads_the_controllers_serial_number(backend):
    from cellrunner.twin.controller import ControllerConfig

    assert backend.serial_number == ControllerConfig.serial_number  # the dashboard's answer


def test_streams_an_approved_trajectory_and_tracks_it(backend):
    approved = approve(wave(500.0, 1.5, backend.read_state().q_rad), 0, "wave")
    t0 = time.monotonic()
    errors = stream(backend, approved)
    elapsed = time.monotonic() - t0
    # paced at the controller rate: never faster; slower only when this machine is loaded
    assert 1.49 < elapsed < 3.0
    # rad; peak joint speed 0.52 rad/s = 1 mrad per period: typically under one period of
    # lag, spikes of several periods when the OS does not schedule us in time
    assert np.median(errors) < 0.002
    assert_tracks(errors)
    backend.stop_motion()
    final = approved.trajectory.q_rad[-1]
    assert wait_until(lambda: np.max(np.abs(backend.read_state().q_rad - final)) < 1e-4, 1.0)
    print(f"\ntracking error max {max(errors):.5f} rad, median {np.median(errors):.5f} rad")


def test_refuses_unsealed_and_wrong_rate_trajectories(backend):
    trajectory = wave(500.0, 0.1, backend.read_state().q_rad)
    forged = ApprovedTrajectory(trajectory, 0, "forged", "0" * 64)
    with pytest.raises(BackendError, match="did not approve"):
        backend.servo(forged, 0)
    with pytest.raises(BackendError, match=r"sampled at 125\.0 Hz"):
        backend.servo(approve(wave(125.0, 0.1, backend.read_state().q_rad), 0, "cb3"), 0)


def test_outputs_and_inputs(backend, twin):
    backend.set_output("DO2", True)
    backend.set_output("TO1", True)
    assert wait_until(lambda: backend.read_state().outputs["DO2"], 1.0)
    assert wait_until(lambda: backend.read_state().outputs["TO1"], 1.0), twin.fault("log 20")
    assert twin.state()["digital_outputs"] & (1 << 2 | 1 << 17) == (1 << 2 | 1 << 17)
    backend.set_output("DO2", False)
    assert wait_until(lambda: not backend.read_state().outputs["DO2"], 1.0)
    twin.fault("input DI4 1")
    assert wait_until(lambda: backend.read_state().inputs["DI4"], 1.0)
    with pytest.raises(BackendError, match="unknown output channel 'DO9'; valid: DO0-7"):
        backend.set_output("DO9", True)


def test_protective_stop_recovery_resumes_streaming(backend, twin):
    q0 = backend.read_state().q_rad
    approved = approve(wave(500.0, 2.0, q0), 3, "interrupted")
    twin_stopped_at = None
    with pytest.raises(SafetyStop) as stop:
        for i in range(len(approved.trajectory.q_rad)):
            if i == 250:
                twin.fault("protective_stop")
                twin_stopped_at = time.monotonic()
            backend.servo(approved, i)
            backend.wait_period()
    assert stop.value.safety == Safety.PROTECTIVE_STOP
    assert i < 300  # noticed within a few cycles
    assert backend.read_state().safety == Safety.PROTECTIVE_STOP
    with pytest.raises(
        BackendError, match="Cannot unlock protective stop until 5s after occurrence"
    ):
        backend.unlock_protective_stop()
    backend.recover_from_protective_stop(timeout_s=8.0)
    assert time.monotonic() - twin_stopped_at >= 5.0
    assert backend.read_state().safety == Safety.NORMAL
    # resume: a fresh approved move from where the arm stopped
    errors = stream(backend, approve(wave(500.0, 0.5, backend.read_state().q_rad), 3, "resume"))
    assert_tracks(errors)


def test_estop_needs_release_then_recovers(backend, twin):
    twin.fault("estop press")
    assert wait_until(lambda: backend.read_state().safety == Safety.EMERGENCY_STOP, 1.0)
    state = backend.read_state()
    assert not state.powered and not state.brakes_released
    with pytest.raises(BackendError, match="still pressed"):
        backend.recover_from_estop()
    twin.fault("estop release")
    assert wait_until(lambda: backend.read_state().safety == Safety.NORMAL, 1.0)
    backend.recover_from_estop()
    state = backend.read_state()
    assert state.powered and state.brakes_released
    errors = stream(backend, approve(wave(500.0, 0.6, state.q_rad), 0, "after-estop"))
    assert_tracks(errors)


def test_connection_loss_reconnects_with_backoff(backend, twin):
    twin.fault("blackout 1.0")
    assert wait_until(lambda: backend.read_state().safety == Safety.DISCONNECTED, 2.0)
    with pytest.raises(BackendError):
        backend.servo(approve(wave(500.0, 0.1, Q_START), 0, "x"), 0)
    t0 = time.monotonic()
    backend.reconnect(timeout_s=10.0)
    assert time.monotonic() - t0 < 6.0
    assert backend.read_state().safety == Safety.NORMAL
    errors = stream(backend, approve(wave(500.0, 0.6, backend.read_state().q_rad), 0, "after"))
    assert_tracks(errors)


def test_reconnect_gives_up_with_peer_unreachable():
    with TwinProcess("ur5e") as twin:
        backend = URBackend(twin.host, UR5E, connect_timeout_s=0.5)
        backend.connect()
        twin.fault("blackout 30")
        t0 = time.monotonic()
        with pytest.raises(PeerUnreachable, match="did not come back"):
            backend.reconnect(timeout_s=1.5)
        assert time.monotonic() - t0 < 4.0
        backend.close()


def test_cb3_streams_at_125_hz():
    with TwinProcess("ur10") as twin:
        backend = URBackend(twin.host, robot_spec("ur10"))
        backend.connect()
        try:
            assert backend.rate_hz == 125.0
            q0 = backend.read_state().q_rad
            t0 = time.monotonic()
            errors = stream(backend, approve(wave(125.0, 1.0, q0), 0, "cb3"))
            assert 0.99 < time.monotonic() - t0 < 2.0
            assert np.median(errors) < 0.01  # one 8 ms period at 0.8 rad/s is 6 mrad
            assert max(errors) < 0.05
            with pytest.raises(BackendError, match="no built-in force/torque sensor"):
                backend.zero_ft_sensor()
        finally:
            backend.close()


def test_powered_off_arm_connects_and_powers_up_on_request():
    with TwinProcess("ur5e", start_running=False, power_on_s=0.2, brake_release_s=0.2) as twin:
        backend = URBackend(twin.host, UR5E)
        backend.connect()
        try:
            state = backend.read_state()
            assert not state.powered and not state.brakes_released
            assert state.safety == Safety.NORMAL
            approved = approve(wave(500.0, 0.6, state.q_rad), 0, "cold")
            with pytest.raises(BackendError, match="not ready"):
                backend.servo(approved, 0)
            assert twin.state()["programs_started"] == 0
            backend.recover_from_estop()
            assert backend.read_state().brakes_released
            assert_tracks(stream(backend, approved))
        finally:
            backend.close()
