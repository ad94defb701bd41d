"""Kinematics and motion profiles of the twin, checked against first principles."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.model.robots import robot_spec
from cellrunner.twin import motion as mo
from cellrunner.twin.kinematics import (
    Kinematics,
    matrix_to_rotvec,
    pose_to_matrix,
    rotvec_to_matrix,
)

SPEC = robot_spec("ur5e")
Q_HOME = np.array([0.1, -1.4, 1.5, -1.7, -1.5, 0.3])


def test_rotvec_roundtrip_including_near_pi():
    rng = np.random.default_rng(1)
    for rv in [*rng.normal(size=(20, 3)), np.array([np.pi - 1e-8, 0, 0]), np.array([0, 2.0, 2.0])]:
        rv = rv if np.linalg.norm(rv) <= np.pi else rv / np.linalg.norm(rv) * (np.pi - 0.1)
        R = rotvec_to_matrix(rv)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.allclose(rotvec_to_matrix(matrix_to_rotvec(R)), R, atol=1e-7)


def test_ur5e_zero_pose_matches_dh_table():
    k = Kinematics(SPEC)
    T = k.flange(np.zeros(6))
    d1, a2, a3, d4, d5, d6 = 0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996
    assert np.allclose(T[:3, 3], [a2 + a3, -(d4 + d6), d1 - d5], atol=1e-9)


def test_jacobian_matches_finite_differences_and_ik_inverts_fk():
    k = Kinematics(SPEC)
    k.set_tcp(np.array([0, 0, 0.15, 0, 0, 0]))
    J = k.jacobian(Q_HOME)
    dq = np.array([1e-5, -2e-5, 1e-5, 3e-5, -1e-5, 2e-5])
    T0, T1 = k.tcp(Q_HOME), k.tcp(Q_HOME + dq)
    assert np.allclose(J[:3] @ dq, T1[:3, 3] - T0[:3, 3], atol=1e-8)
    target = k.tcp(Q_HOME + np.array([0.2, 0.1, -0.1, 0.1, 0.2, -0.2]))
    q = k.inverse(target, Q_HOME)
    assert q is not None
    assert np.allclose(k.tcp(q), target, atol=1e-6)


@pytest.mark.parametrize("distance,v,a", [(1.0, 1.0, 2.0), (0.1, 1.0, 2.0), (2.0, 0.5, 10.0)])
def test_trapezoid_respects_limits_and_ends_at_distance(distance, v, a):
    p = mo.Trapezoid(distance, v, a)
    t = np.linspace(0, p.duration, 2001)
    s = np.array([p.position(x) for x in t])
    speed = np.diff(s) / np.diff(t)
    assert s[-1] == pytest.approx(distance)
    assert speed.max() <= v + 1e-6
    assert np.abs(np.diff(speed) / np.diff(t)[1:]).max() <= a * 1.01
    assert all(p.time_at(p.position(x)) == pytest.approx(x, abs=1e-6) for x in t[::97])


def test_movej_synchronizes_joints_and_blended_path_does_not_stop():
    k = Kinematics(SPEC)
    qd_max = np.radians(SPEC.joint_speed_max_deg_s)
    w1, w2 = Q_HOME + [0.5, 0, 0, 0, 0, 0], Q_HOME + [0.5, -0.4, 0, 0, 0, 0]
    path = mo.JointPath(Q_HOME, [(w1, 1.0, 2.0, 0.05), (w2, 1.0, 2.0, 0.0)], k, qd_max)
    stop = mo.JointPath(Q_HOME, [(w1, 1.0, 2.0, 0.0), (w2, 1.0, 2.0, 0.0)], k, qd_max)
    assert path.duration_s < stop.duration_s

    def run(gen):
        q, qd, speeds = Q_HOME.copy(), np.zeros(6), []
        for _ in range(5000):
            q, qd, done = gen.advance(q, qd, 0.002)
            speeds.append(np.linalg.norm(qd))
            if done:
                return q, speeds
        raise AssertionError("did not finish")

    q_end, speeds = run(path)
    assert np.allclose(q_end, w2, atol=1e-9)
    assert min(speeds[100:-100]) > 0.05
    q_end, speeds = run(stop)
    assert min(speeds[100:-100]) < 0.005  # without blend it stops at w1


def test_stop_decelerates_all_joints_together():
    stop = mo.Stop(decel=4.0)
    q, qd = Q_HOME.copy(), np.array([1.0, -0.5, 0.2, 0, 0, 0])
    steps = 0
    while True:
        q, qd_new, done = stop.advance(q, qd, 0.002)
        assert np.all(np.abs(qd_new) <= np.abs(qd) + 1e-12)
        qd, steps = qd_new, steps + 1
        if done:
            break
    assert steps * 0.002 == pytest.approx(1.0 / 4.0, abs=0.004)


def test_pose_matrix_roundtrip():
    pose = np.array([0.3, -0.2, 0.5, 0.1, -2.0, 0.4])
    T = pose_to_matrix(pose)
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3))
    assert np.allclose(T[:3, 3], pose[:3])


def test_movel_paces_by_the_slower_of_position_and_rotation():
    k = Kinematics(SPEC)
    qd_max = np.radians(SPEC.joint_speed_max_deg_s)
    q_target = Q_HOME + np.array([0, 0, 0, 0, 0, 0.2])  # mostly a turn of the tool
    pose = k.tcp_pose(q_target)
    pose[0] += 2e-6  # and a few micrometres of travel
    line = mo.LinearPath(Q_HOME, [(pose, 0.25, 1.2, 0.0)], k, qd_max)
    assert line.duration_s == pytest.approx(mo.Trapezoid(0.2, 0.25, 1.2).duration, rel=1e-3)
    q, qd = Q_HOME.copy(), np.zeros(6)
    for _ in range(1000):
        q, qd, done = line.advance(q, qd, 0.002)
        if done:
            break
    assert done and np.allclose(k.tcp_pose(q), pose, atol=1e-6)
