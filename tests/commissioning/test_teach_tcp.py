"""`teach` and `calibrate-tcp` against `cellrunner twin`: the arm is moved with the
unmodified ur_rtde client (as a person jogs it), the command reads it through ur_rtde and
answers are typed on its standard input. Judged: a frame from three points within 0.5 mm /
0.1 deg of the truth, a hidden TCP within 0.5 mm, and a cell file that changes in the
written pose's line only."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from cellrunner.model.geometry import pose_matrix, rot_rpy_deg
from tests.commissioning.conftest import CELL, cli, twin, write_project
from tests.conftest import ROOT

HOST = "127.0.0.152"


class Hand:
    """Moves the twin's arm through ur_rtde: the TCP (or the flange) to a world pose."""

    def __init__(self, cell_path):
        import rtde_control

        from cellrunner.model.load import load_cell
        from cellrunner.planning.world import CellWorld

        self.kinematics = CellWorld(load_cell(cell_path)).kinematics
        self.T_flange_tcp = (
            self.kinematics.T_flange_tcp if hasattr(self.kinematics, "T_flange_tcp") else None
        )
        self.control = rtde_control.RTDEControlInterface(HOST)
        self.q = np.radians([0, -90, 90, -90, -90, 0])

    def tcp_to(self, T_world_tcp: np.ndarray) -> None:
        q = self.kinematics.ik_nearest(T_world_tcp, self.q)
        assert self.control.moveJ(list(q), 2.0, 6.0)
        self.q = q

    def close(self) -> None:
        self.control.stopScript()
        self.control.disconnect()


def _session(args, on_prompt):
    """Run a commissioning command, calling ``on_prompt(n)`` before answering its n-th
    Enter prompt; returns (exit code, stdout, stderr)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.cli.main", *args],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen = []
    try:
        deadline = time.monotonic() + 100
        n = 0
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            seen.append(line)
            if "press Enter" in line:
                on_prompt(n)
                n += 1
                proc.stdin.write("\n")
                proc.stdin.flush()
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out, "".join(seen) + err


DOWN = rot_rpy_deg([180, 0, 0])


def _tcp_pose(p, R=DOWN):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def test_a_frame_taught_from_three_points_matches_the_true_frame(tmp_path):
    cell, _ = write_project(tmp_path)
    T_true = pose_matrix([0.55, -0.15, 0.86], [0, 0, 30])
    x, y, o = T_true[:3, 0], T_true[:3, 1], T_true[:3, 3]
    points = [o, o + 0.15 * x, o + 0.05 * x + 0.12 * y]
    with twin(cell, HOST):
        hand = Hand(cell)
        try:
            code, out, err = _session(
                ["teach", str(cell), "plate", "--robot-host", HOST, "--points", "3", "--yes"],
                lambda n: hand.tcp_to(_tcp_pose(points[n])),
            )
        finally:
            hand.close()
    assert code == 0, err[-2000:]
    after = cell.read_text()
    added = [line for line in after.splitlines(True) if line not in CELL.splitlines(True)]
    assert len(added) == 1 and added[0].startswith("  plate: {xyz: [")
    assert after.replace(added[0], "") == CELL, "every other byte as it was"
    assert out.count("\n+  plate: {xyz:") == 1  # the diff, on stdout
    from cellrunner.model.load import load_cell

    frame = load_cell(cell).cell.frames["plate"]
    T = frame.matrix()
    assert np.linalg.norm(T[:3, 3] - T_true[:3, 3]) < 0.5e-3
    R = T_true[:3, :3].T @ T[:3, :3]
    assert np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))) < 0.1


def test_teach_one_point_rewrites_only_that_frame_and_asks_first(tmp_path):
    cell, _ = write_project(tmp_path)
    T_goal = pose_matrix([0.68, -0.41, 0.86], [180, 0, 40])
    with twin(cell, HOST):
        hand = Hand(cell)
        try:
            hand.tcp_to(T_goal)
            proc = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "cellrunner.cli.main",
                    "teach",
                    str(cell),
                    "pick",
                    "--robot-host",
                    HOST,
                ],
                input="\nn\n",
                capture_output=True,
                text=True,
                cwd=ROOT,
                timeout=100,
            )
            assert proc.returncode == 0, proc.stderr
            assert cell.read_text() == CELL, "answered n: nothing written"
            assert (
                "left unchanged" in proc.stderr
                and "-  pick: {xyz: [0.7, -0.4, 0.83]" in proc.stdout
            )
            proc = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "cellrunner.cli.main",
                    "teach",
                    str(cell),
                    "pick",
                    "--robot-host",
                    HOST,
                ],
                input="\ny\n",
                capture_output=True,
                text=True,
                cwd=ROOT,
                timeout=100,
            )
        finally:
            hand.close()
    assert proc.returncode == 0, proc.stderr
    old = CELL.splitlines(True)
    new = cell.read_text().splitlines(True)
    changed = [i for i, (a, b) in enumerate(zip(old, new, strict=True)) if a != b]
    assert len(old) == len(new) and len(changed) == 1
    assert new[changed[0]].endswith("]}   # infeed\n"), "the comment after the frame stays"
    from cellrunner.model.load import load_cell

    T = load_cell(cell).cell.frames["pick"].matrix()
    assert np.linalg.norm(T[:3, 3] - T_goal[:3, 3]) < 0.5e-3
    assert "mm and" in proc.stderr and "from the pose in the file" in proc.stderr


def test_calibrate_tcp_recovers_a_hidden_tcp(tmp_path):
    cell, _ = write_project(tmp_path)
    hidden_m = np.array([0.012, -0.008, 0.183])  # the real tool; the file says [0, 0, 0.17]
    point = np.array([0.6, 0.1, 0.95])
    tilts = [
        [0, 0, 0],
        [0, 0, 0],
        [25, 0, 0],
        [0, 25, 0],
        [-15, -15, 30],
        [10, -20, -60],
    ]  # the 2nd repeats
    T_flange_tcp_file = pose_matrix([0, 0, 0.17])

    def touch(n):
        R = DOWN @ rot_rpy_deg(tilts[n])
        T_world_flange = _tcp_pose(point - R @ hidden_m, R)
        hand.tcp_to(T_world_flange @ T_flange_tcp_file)

    with twin(cell, HOST):
        hand = Hand(cell)
        try:
            code, _out, err = _session(
                ["calibrate-tcp", str(cell), "--robot-host", HOST, "--poses", "5", "--yes"], touch
            )
        finally:
            hand.close()
    assert code == 0, err[-2000:]
    assert (
        "refused: this pose is turned only 0.0 deg from pose 1; turn the tool at least 15 deg"
        in err
    )
    from cellrunner.model.load import load_cell

    tcp = np.array(load_cell(cell).cell.tool.tcp.xyz)
    assert np.linalg.norm(tcp - hidden_m) < 0.5e-3, tcp
    assert cell.read_text() == CELL.replace(
        "tcp: {xyz: [0, 0, 0.17]}", "tcp: {xyz: [0.012, -0.008, 0.183]}"
    )
    assert "residual rms 0.0" in err


def test_calibrate_tcp_refuses_poses_about_one_axis():
    from cellrunner.commissioning.tcp import TcpError, solve_tcp

    hidden = np.array([0.01, 0.02, 0.15])
    poses = []
    for angle in (0, 30, 60, 90):  # all about the flange's Z: the TCP's Z is not observable
        R = DOWN @ rot_rpy_deg([0, 0, angle])
        poses.append(_tcp_pose(np.array([0.5, 0, 1.0]) - R @ hidden, R))
    with pytest.raises(
        TcpError, match=r"the poses turn the tool about too few axes \(conditioning 0\.0"
    ):
        solve_tcp(poses)


def test_bad_arguments_are_exit_2_and_an_absent_controller_exit_3(tmp_path):
    cell, _ = write_project(tmp_path)
    r = cli("teach", str(cell), "2nd frame", "--robot-host", "127.0.0.159")
    assert r.returncode == 2 and "frame name '2nd frame': use letters, digits, _ and -" in r.stderr
    r = cli("teach", str(cell), "pick", "--robot-host", "127.0.0.159", "--points", "2")
    assert r.returncode == 2 and "--points 2: give 1 (the TCP pose) or 3" in r.stderr
    r = cli("calibrate-tcp", str(cell), "--robot-host", "127.0.0.159", "--poses", "3")
    assert r.returncode == 2 and "--poses 3: the TCP needs at least 4" in r.stderr
    for command in (["teach", str(cell), "pick"], ["calibrate-tcp", str(cell)]):
        r = cli(*command, "--robot-host", "127.0.0.159", input="\n")
        assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    r = cli("jog", str(cell), "--robot-host", "127.0.0.159", stdin=subprocess.DEVNULL)
    assert r.returncode == 2 and "jog needs a terminal" in r.stderr
    assert cell.read_text() == CELL
