"""The unmodified ur_rtde client against the virtual controller, in another process.

One twin per test module section (module-scoped fixtures) keeps the run short; tests that
change safety state get their own twin.
"""

from __future__ import annotations

import json
import math
import socket
import struct
import time

import dashboard_client
import numpy as np
import pytest
import rtde_control
import rtde_io
import rtde_receive

from tests.twin.twin_process import Dashboard, TwinProcess, wait_until

UNLOCK_REFUSED = (
    "Cannot unlock protective stop until 5s after occurrence. "
    "Always inspect cause of protective stop before unlocking"
)


@pytest.fixture(scope="module")
def twin():
    with TwinProcess("ur5e") as t:
        yield t


@pytest.fixture(scope="module")
def receive(twin):
    r = rtde_receive.RTDEReceiveInterface(twin.host)
    yield r
    r.disconnect()


@pytest.fixture(scope="module")
def control(twin, receive):
    c = rtde_control.RTDEControlInterface(twin.host)
    yield c
    c.stopScript()
    c.disconnect()


# ----------------------------------------------------------------------------- dashboard


def test_dashboard_greeting_and_status_replies(twin):
    d = Dashboard(twin.host)
    try:
        assert d.greeting == "Connected: Universal Robots Dashboard Server"
        assert d.ask("robotmode") == "Robotmode: RUNNING"
        assert d.ask("safetymode") == "Safetymode: NORMAL"
        assert d.ask("safetystatus") == "Safetystatus: NORMAL"
        assert d.ask("is in remote control") == "true"
        assert d.ask("get robot model") == "UR5"
        assert d.ask("get serial number").isdigit()
        assert d.ask("PolyscopeVersion").startswith("URSoftware 5.")
        assert d.ask("version").split(".")[0] == "5"
        assert d.ask("close popup") == "closing popup"
        assert d.ask("close safety popup") == "closing safety popup"
        assert d.ask("load cell.urp") == "Loading program: cell.urp"
        assert d.ask("get loaded program") == "Loaded program: cell.urp"
        assert d.ask("running") in ("Program running: false", "Program running: true")
        assert d.ask("make coffee") == "could not understand: 'make coffee'"
        assert d.ask("quit") == "Disconnected"
    finally:
        d.close()


def test_dashboard_client_library_parses_replies(twin):
    d = dashboard_client.DashboardClient(twin.host)
    d.connect()
    try:
        assert d.polyscopeVersion().startswith("5.11")
        assert d.isInRemoteControl() is True
        assert d.getSerialNumber().isdigit()
        assert d.robotmode() == "Robotmode: RUNNING"
        d.unlockProtectiveStop()  # nothing to unlock: accepted
    finally:
        d.disconnect()


def test_local_control_refuses_robot_commands(twin):
    twin.fault("remote off")
    d = Dashboard(twin.host)
    try:
        assert d.ask("is in remote control") == "false"
        assert d.ask("power off").startswith("Command is not allowed due to safety reasons")
        assert d.ask("robotmode") == "Robotmode: RUNNING"  # queries still answered
    finally:
        d.close()
        twin.fault("remote on")


# ----------------------------------------------------------------------------- RTDE


def _rtde_msg(kind: str, payload: bytes = b"") -> bytes:
    return struct.pack(">HB", 3 + len(payload), ord(kind)) + payload


def _read_msg(sock: socket.socket) -> tuple[str, bytes]:
    head = b""
    while len(head) < 3:
        head += sock.recv(3 - len(head))
    size, kind = struct.unpack(">HB", head)
    body = b""
    while len(body) < size - 3:
        body += sock.recv(size - 3 - len(body))
    return chr(kind), body


def test_rtde_framing_survives_split_and_coalesced_messages(twin):
    with socket.create_connection((twin.host, 30004), timeout=3) as sock:
        request = _rtde_msg("V", struct.pack(">H", 2))
        for byte in request:  # one byte per segment
            sock.sendall(bytes([byte]))
            time.sleep(0.002)
        assert _read_msg(sock) == ("V", b"\x01")
        names = b"timestamp,actual_q,no_such_variable"
        coalesced = _rtde_msg("v") + _rtde_msg("O", struct.pack(">d", 500.0) + names)
        sock.sendall(coalesced)
        kind, body = _read_msg(sock)
        assert kind == "v" and struct.unpack(">IIII", body)[:2] == (5, 11)
        kind, body = _read_msg(sock)
        assert kind == "O" and body[0] == 0
        assert body[1:].decode() == "DOUBLE,VECTOR6D,NOT_FOUND"


def test_rtde_streams_500_hz_on_e_series(twin):
    with socket.create_connection((twin.host, 30004), timeout=3) as sock:
        sock.sendall(_rtde_msg("V", struct.pack(">H", 2)))
        _read_msg(sock)
        sock.sendall(_rtde_msg("O", struct.pack(">d", 500.0) + b"timestamp,robot_mode"))
        kind, body = _read_msg(sock)
        assert (kind, body[1:]) == ("O", b"DOUBLE,INT32")
        sock.sendall(_rtde_msg("S"))
        assert _read_msg(sock) == ("S", b"\x01")
        stamps = []
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            kind, body = _read_msg(sock)
            if kind == "U":
                stamps.append(struct.unpack_from(">d", body, 1)[0])
    steps = np.diff(stamps)
    assert len(stamps) > 400  # ~500 in one wall-clock second
    assert np.allclose(steps, 0.002, atol=1e-6)


def test_unknown_output_variable_is_refused_like_the_controller(twin):
    with pytest.raises(RuntimeError, match=r"not found by the controller: \[no_such_variable\]"):
        rtde_receive.RTDEReceiveInterface(twin.host, -1.0, ["actual_q", "no_such_variable"])


def test_receive_full_default_table(receive):
    assert len(receive.getActualQ()) == 6
    assert receive.getRobotMode() == 7
    assert receive.getSafetyMode() == 1
    assert receive.getSafetyStatusBits() & 1
    assert len(receive.getFtRawWrench()) == 6
    assert receive.getPayload() >= 0.0
    assert len(receive.getPayloadCog()) == 3
    assert receive.getOutputIntRegister(12) == 0


def test_two_receivers_at_once(twin, receive):
    other = rtde_receive.RTDEReceiveInterface(twin.host)
    try:
        t0 = other.getTimestamp()
        assert wait_until(lambda: other.getTimestamp() > t0 + 0.05, 2.0)
        assert abs(other.getTimestamp() - receive.getTimestamp()) < 0.05
    finally:
        other.disconnect()


# ----------------------------------------------------------------------------- motion


def test_movej_reaches_target_with_trapezoid_timing(control, receive):
    q0 = np.array(receive.getActualQ())
    target = q0 + np.array([0.4, -0.2, 0.1, 0.0, 0.2, -0.3])
    t0 = time.monotonic()
    assert control.moveJ(target.tolist(), 1.0, 2.0)
    elapsed = time.monotonic() - t0
    assert np.allclose(receive.getActualQ(), target, atol=1e-4)
    # leading joint 0.4 rad at v=1.0, a=2.0: 0.5 s accel + 0.0 cruise (triangular: 2*sqrt(0.4/2))
    assert 0.85 < elapsed < 1.3


def test_movel_keeps_a_straight_line(control, receive):
    p0 = np.array(receive.getActualTCPPose())
    target = p0 + np.array([0.05, 0.08, -0.06, 0, 0, 0])
    assert control.moveL(target.tolist(), 0.25, 1.2, True)  # asynchronous
    deviations = []
    t_end = time.monotonic() + 3.0
    while time.monotonic() < t_end:
        p = np.array(receive.getActualTCPPose())
        along = np.dot(p[:3] - p0[:3], (target - p0)[:3]) / np.linalg.norm((target - p0)[:3]) ** 2
        deviations.append(np.linalg.norm(p[:3] - (p0[:3] + along * (target - p0)[:3])))
        if control.getAsyncOperationProgress() < 0 and np.allclose(p[:3], target[:3], atol=1e-5):
            break
        time.sleep(0.004)
    assert np.allclose(receive.getActualTCPPose()[:3], target[:3], atol=1e-5)
    assert max(deviations) < 1e-4


def test_movej_path_with_blend_passes_near_waypoints(control, receive):
    q0 = receive.getActualQ()
    w1 = [q0[0] + 0.3, *q0[1:]]
    w2 = [q0[0] + 0.3, q0[1] - 0.2, *q0[2:]]
    path = [[*w1, 1.0, 2.0, 0.05], [*w2, 1.0, 2.0, 0.0]]
    qd_min_norm = []
    assert control.moveJ(path, True)
    t_end = time.monotonic() + 4.0
    while time.monotonic() < t_end and control.getAsyncOperationProgress() >= 0:
        qd_min_norm.append(np.linalg.norm(receive.getActualQd()))
        time.sleep(0.004)
    assert np.allclose(receive.getActualQ(), w2, atol=1e-4)
    # blended: the arm never stops in between (the middle of the motion keeps speed)
    middle = qd_min_norm[len(qd_min_norm) // 4 : 3 * len(qd_min_norm) // 4]
    assert min(middle) > 0.05


def test_servoj_stream_is_tracked(control, receive):
    q0 = np.array(receive.getActualQ())
    errors = []
    for i in range(750):  # 1.5 s at 500 Hz
        t_start = control.initPeriod()
        q = q0.copy()
        q[0] += 0.15 * math.sin(2 * math.pi * i / 750)
        q[2] += 0.1 * (1 - math.cos(2 * math.pi * i / 750))
        control.servoJ(q.tolist(), 0.5, 0.5, 0.002, 0.1, 300)
        if i > 50:
            errors.append(np.max(np.abs(np.array(receive.getActualQ()) - q)))
        control.waitPeriod(t_start)
    control.servoStop()
    assert np.percentile(errors, 95) < 0.01  # rad; speed ~0.6 rad/s peak -> a few periods lag
    assert wait_until(lambda: np.linalg.norm(receive.getActualQd()) < 1e-6, 2.0)


def test_speedj_moves_and_speed_stop_halts(control, receive):
    q0 = receive.getActualQ()[5]
    control.speedJ([0, 0, 0, 0, 0, 0.5], 2.0, 0.002)
    time.sleep(0.4)
    moving = receive.getActualQd()[5]
    control.speedStop(5.0)
    assert moving == pytest.approx(0.5, abs=0.01)
    assert receive.getActualQ()[5] > q0 + 0.1
    assert abs(receive.getActualQd()[5]) < 1e-6


def test_set_tcp_and_payload_show_on_the_receive_side(control, receive, twin):
    flange = receive.getActualTCPPose()
    assert control.setTcp([0, 0, 0.15, 0, 0, 0])
    assert control.setPayload(1.2, [0, 0, 0.05])
    assert wait_until(lambda: abs(receive.getPayload() - 1.2) < 1e-9, 1.0)
    tcp = receive.getActualTCPPose()
    assert np.linalg.norm(np.array(tcp[:3]) - np.array(flange[:3])) == pytest.approx(0.15, abs=1e-6)
    assert twin.state()["tcp_offset"][2] == pytest.approx(0.15)
    assert control.setTcp([0, 0, 0, 0, 0, 0])


# ----------------------------------------------------------------------------- IO


def test_io_interface_outputs_show_on_receive_side(twin, receive):
    io = rtde_io.RTDEIOInterface(twin.host)
    try:
        assert io.setStandardDigitalOut(3, True)
        assert io.setToolDigitalOut(1, True)
        assert wait_until(
            lambda: receive.getDigitalOutState(3) and receive.getDigitalOutState(17), 1.0
        )
        assert not receive.getDigitalOutState(2)
        assert io.setStandardDigitalOut(3, False)
        assert wait_until(lambda: not receive.getDigitalOutState(3), 1.0)
        assert io.setAnalogOutputVoltage(0, 0.5)
        assert wait_until(lambda: receive.getStandardAnalogOutput0() == pytest.approx(0.5), 1.0)
        assert io.setInputIntRegister(18, 42)
        assert io.setSpeedSlider(0.5)
        assert wait_until(lambda: receive.getTargetSpeedFraction() == pytest.approx(0.5), 1.0)
        assert io.setSpeedSlider(1.0)
    finally:
        io.disconnect()


def test_inputs_forced_on_the_fault_channel_show_on_receive_side(twin, receive):
    twin.fault("input DI1 1")
    assert wait_until(lambda: receive.getDigitalInState(1), 1.0)
    twin.fault("input DI1 clear")
    assert wait_until(lambda: not receive.getDigitalInState(1), 1.0)


def test_custom_script_function_runs_simple_program(control, receive):
    assert control.sendCustomScriptFunction("set_do", "set_standard_digital_out(5, True)")
    assert wait_until(lambda: receive.getDigitalOutState(5), 1.0)
    assert control.isProgramRunning()  # the control script was put back


# ----------------------------------------------------------------------------- safety


def test_protective_stop_unlock_timing_and_reupload():
    with TwinProcess("ur5e") as twin:
        receive = rtde_receive.RTDEReceiveInterface(twin.host)
        control = rtde_control.RTDEControlInterface(twin.host)
        d = Dashboard(twin.host)
        try:
            assert control.triggerProtectiveStop()
            t_stop = time.monotonic()
            assert wait_until(receive.isProtectiveStopped, 1.0)
            assert receive.getSafetyMode() == 3
            assert d.ask("safetystatus") == "Safetystatus: PROTECTIVE_STOP"
            assert wait_until(lambda: not control.isProgramRunning(), 1.0)
            assert not control.moveJ(receive.getActualQ(), 1.0, 1.0)  # refused while stopped
            assert d.ask("unlock protective stop") == UNLOCK_REFUSED
            time.sleep(max(0.0, t_stop + 5.05 - time.monotonic()))
            assert d.ask("close safety popup") == "closing safety popup"
            assert d.ask("unlock protective stop") == "Protective stop releasing"
            assert wait_until(lambda: receive.getSafetyMode() == 1, 1.0)
            assert control.reuploadScript()
            assert wait_until(control.isProgramRunning, 2.0)
            q = receive.getActualQ()
            q[0] += 0.1
            assert control.moveJ(q, 1.0, 2.0)
            assert receive.getActualQ()[0] == pytest.approx(q[0], abs=1e-4)
        finally:
            d.close()
            control.disconnect()
            receive.disconnect()


def test_collision_and_estop_cycle():
    with TwinProcess("ur5e", unlock_delay_s=5.0, power_on_s=0.2, brake_release_s=0.2) as twin:
        receive = rtde_receive.RTDEReceiveInterface(twin.host)
        control = rtde_control.RTDEControlInterface(twin.host)
        d = Dashboard(twin.host)
        try:
            q = receive.getActualQ()
            q[0] += 1.0
            assert control.moveJ(q, 0.5, 1.0, True)
            time.sleep(0.3)
            twin.fault("collision on")
            assert wait_until(receive.isProtectiveStopped, 1.0)
            assert wait_until(lambda: np.linalg.norm(receive.getActualQd()) == 0.0, 1.0)
            assert receive.getActualQ()[0] < q[0] - 0.1  # stopped short of the target
            twin.fault("collision off")

            twin.fault("estop press")
            assert wait_until(receive.isEmergencyStopped, 1.0)
            assert d.ask("safetystatus") == "Safetystatus: ROBOT_EMERGENCY_STOP"
            assert d.ask("robotmode") == "Robotmode: POWER_OFF"
            assert not control.isProgramRunning()
            assert d.ask("power on") == "Powering on"
            time.sleep(0.3)
            assert d.ask("robotmode") == "Robotmode: POWER_OFF"  # not while pressed
            twin.fault("estop release")
            assert wait_until(lambda: d.ask("safetystatus") == "Safetystatus: NORMAL", 1.0)
            assert d.ask("power on") == "Powering on"
            assert wait_until(lambda: d.ask("robotmode") == "Robotmode: IDLE", 2.0)
            assert d.ask("brake release") == "Brake releasing"
            assert wait_until(lambda: d.ask("robotmode") == "Robotmode: RUNNING", 2.0)
            assert control.reuploadScript()
            assert wait_until(control.isProgramRunning, 2.0)
        finally:
            d.close()
            control.disconnect()
            receive.disconnect()


def test_rtde_watchdog_stops_the_program():
    with TwinProcess("ur5e") as twin:
        control = rtde_control.RTDEControlInterface(twin.host)
        try:
            assert control.setWatchdog(20.0)
            assert control.kickWatchdog()
            assert control.isProgramRunning()
            assert wait_until(lambda: not control.isProgramRunning(), 1.0)  # no more kicks
            assert any("watchdog" in line for line in twin.fault("log").split('"'))
        finally:
            control.disconnect()


# ----------------------------------------------------------------------------- CB3


def test_cb3_controller_answers_as_cb3_at_125_hz():
    with TwinProcess("ur5") as twin:
        d = Dashboard(twin.host)
        assert d.ask("PolyscopeVersion").startswith("URSoftware 3.")
        d.close()
        receive = rtde_receive.RTDEReceiveInterface(twin.host)
        control = rtde_control.RTDEControlInterface(twin.host)
        try:
            t0, wall0 = receive.getTimestamp(), time.monotonic()
            time.sleep(0.5)
            assert receive.getTimestamp() - t0 == pytest.approx(time.monotonic() - wall0, abs=0.05)
            stamps = set()
            t_end = time.monotonic() + 0.3
            while time.monotonic() < t_end:
                stamps.add(round(receive.getTimestamp(), 4))
                time.sleep(0.001)
            steps = np.diff(sorted(stamps))
            assert np.median(steps) == pytest.approx(0.008, abs=1e-6)
            with pytest.raises(RuntimeError, match="ft_raw_wrench"):
                rtde_receive.RTDEReceiveInterface(twin.host, -1.0, ["ft_raw_wrench"])
            q = receive.getActualQ()
            q[1] -= 0.2
            assert control.moveJ(q, 1.0, 2.0)
            assert receive.getActualQ()[1] == pytest.approx(q[1], abs=1e-4)
        finally:
            control.disconnect()
            receive.disconnect()


def test_kinematics_queries_and_rotation_only_movel(control, receive):
    # (getForwardKinematics(q) with a zero TCP sends recipe 6, whose script reads the TCP
    # from stale registers: a ur_rtde quirk a real controller shares; use the other forms)
    q = receive.getActualQ()
    pose = control.getForwardKinematics()
    assert np.allclose(pose, receive.getActualTCPPose(), atol=1e-6)
    with_tool = control.getForwardKinematics(q, [0, 0, 0.1, 0, 0, 0])
    assert np.linalg.norm(np.array(with_tool[:3]) - pose[:3]) == pytest.approx(0.1, abs=1e-6)
    assert np.allclose(control.getInverseKinematics(pose, q), q, atol=1e-5)
    assert control.getInverseKinematicsHasSolution(pose)
    assert np.allclose(
        control.poseTrans([0, 0, 0.1, 0, 0, 0], [0.1, 0, 0, 0, 0, 0]), [0.1, 0, 0.1, 0, 0, 0]
    )
    target = list(q)
    target[5] += 0.2  # the TCP turns in place (flange on the wrist-3 axis)
    assert control.moveL_FK(target, 0.25, 1.2)
    assert np.allclose(receive.getActualQ(), target, atol=1e-4)
    assert wait_until(control.isSteady, 1.0)


def test_move_until_contact_stops_on_tool_force(control, receive, twin):
    import threading

    z0 = receive.getActualTCPPose()[2]
    presser = threading.Timer(0.4, lambda: twin.fault("wrench 0 0 25 0 0 0"))
    presser.start()
    try:
        t0 = time.monotonic()
        assert control.moveUntilContact([0, 0, -0.05, 0, 0, 0])
        elapsed = time.monotonic() - t0
    finally:
        presser.join()
        twin.fault("wrench 0 0 0 0 0 0")
    travelled = z0 - receive.getActualTCPPose()[2]
    assert 0.35 < elapsed < 2.0
    assert 0.01 < travelled < 0.05  # moved down at 5 cm/s until the force came


def test_dashboard_play_pause_stop_of_a_loaded_program():
    with TwinProcess("ur5e") as twin:
        d = Dashboard(twin.host)
        try:
            assert d.ask("play") == "Failed to execute: play"  # nothing loaded
            assert d.ask("load /programs/cell.urp") == "Loading program: /programs/cell.urp"
            assert d.ask("play") == "Starting program"
            assert d.ask("programState") == "PLAYING /programs/cell.urp"
            assert d.ask("running") == "Program running: true"
            assert d.ask("pause") == "Pausing program"
            assert d.ask("programState") == "PAUSED /programs/cell.urp"
            assert d.ask("play") == "Starting program"
            assert d.ask("stop") == "Stopped"
            assert d.ask("programState").startswith("STOPPED")
            twin.fault("estop press system")
            assert d.ask("safetystatus") == "Safetystatus: SYSTEM_EMERGENCY_STOP"
            assert d.ask("play") == "Failed to execute: play"
        finally:
            d.close()


def test_script_port_runs_simple_programs_and_refuses_others():
    with TwinProcess("ur5e", loopback={"DO0": "DI0"}) as twin:
        receive = rtde_receive.RTDEReceiveInterface(twin.host)
        try:
            q = receive.getActualQ()
            target = [q[0] + 0.2, *q[1:]]
            with socket.create_connection((twin.host, 30002), timeout=3) as sock:
                sock.sendall(
                    (
                        "def cell_test():\n"
                        f"  movej({target}, a=2.0, v=1.0)\n"
                        "  set_standard_digital_out(0, True)\n"
                        "  write_output_integer_register(13, 7)\n"
                        "end\n"
                    ).encode()
                )
                assert wait_until(lambda: receive.getDigitalOutState(0), 3.0)
                assert np.allclose(receive.getActualQ(), target, atol=1e-5)
                assert wait_until(lambda: receive.getDigitalInState(0), 1.0)  # DO0 -> DI0 wiring
                assert receive.getOutputIntRegister(13) == 7
                sock.sendall(b'socket_open("10.0.0.1", 80)\n')
                assert wait_until(
                    lambda: "program refused: unsupported statement" in twin.fault("log"), 1.0
                )
        finally:
            receive.disconnect()


def test_fault_channel_names_known_commands_on_error(twin):
    with pytest.raises(ValueError, match=r"unknown command 'bogus'; known: ping, state"):
        twin.fault("bogus")
    with pytest.raises(ValueError, match=r"unknown channel 'XX9'"):
        twin.fault("input XX9 1")
    time.sleep(0.3)
    timing = json.loads(twin.fault("timing"))
    assert timing["period_s"] == pytest.approx(0.002)
    assert timing["n"] > 100
    assert timing["period_p50_s"] == pytest.approx(0.002, abs=2e-4)
