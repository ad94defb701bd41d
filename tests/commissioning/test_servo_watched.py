"""`cellrunner jog` of a watched cell (SPEC section 12): the zone watch, fed by the twin's
depth camera through the virtual controller, governs a push commanded over UDP."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import numpy as np

from cellrunner.model.load import load_cell
from cellrunner.planning.world import CellWorld
from tests.commissioning.conftest import fault, twin
from tests.commissioning.servo_rig import HOST, Recorder, jog_udp, send
from tests.conftest import ROOT
from tests.rig import free_port

#: a 0.1 m box 0.2 m to world +Y of the TCP at home (0.49, 0.13, 1.24), seen only by the camera
BOX_XYZ, BOX_HALF = np.array([0.49, 0.33, 1.24]), 0.05
INTRUDER = (
    "sim:\n  intruders:\n    - {name: crate, box: {size: [0.1, 0.1, 0.1]}, "
    f"pose: {{xyz: [{BOX_XYZ[0]}, {BOX_XYZ[1]}, {BOX_XYZ[2]}]}}, appear: 0}}\n"
)
PADDING_M = 0.03
STOPPED = re.compile(
    r"stopped: watched zone: occupied voxel at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) m"
)


def _push(tmp_path: Path, intruder: bool) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Through a 5 s push at 50 mm/s toward world +Y: the flange's world positions (m),
    the TCP's at the end (from the joints), and jog's status lines."""
    text = (ROOT / "cells" / "watched_ur5e.yaml").read_text()
    if intruder:
        text = text.replace("sim:\n", INTRUDER, 1)
    text = text.replace(" tasks/", f" {ROOT}/tasks/")
    cell = tmp_path / f"watched_{intruder}.yaml"
    cell.write_text(text)
    port = free_port("127.0.0.1")
    with twin(cell, HOST), jog_udp(cell, port) as (_proc, lines):
        rec = Recorder(HOST)
        try:
            time.sleep(1.0)  # a few depth images into the map
            send(port, "0,-0.05,0:5.0")  # base -Y is world +Y (the mount turns the base)
            time.sleep(0.3)
            q = np.array(json.loads(fault(HOST, "state"))["q_rad"])
        finally:
            rec.close()
    _, p = rec.arrays()
    flange = np.column_stack([-p[:, 0], -p[:, 1], p[:, 2] + 0.9])
    tcp = CellWorld(load_cell(cell)).kinematics.p_world_tcp(q)
    return flange, tcp, lines


def test_a_watched_jog_stops_short_of_what_the_depth_camera_sees(tmp_path):
    free, _, free_lines = _push(tmp_path, intruder=False)
    blocked, tcp, lines = _push(tmp_path, intruder=True)
    assert not any("watched zone" in line for line in free_lines), "".join(free_lines)
    # the push moves toward the box, so the TCP is nearest it at the end: outside the padding
    outside = np.maximum(np.abs(tcp - BOX_XYZ) - BOX_HALF, 0.0)
    assert np.linalg.norm(outside) > PADDING_M, tcp
    free_travel = free[-1, 1] - free[0, 1]
    blocked_travel = blocked[-1, 1] - blocked[0, 1]
    assert free_travel > 0.2, free_travel  # 0.25 m asked
    assert 0.005 < blocked_travel < free_travel - 0.1, (blocked_travel, free_travel)
    # the status names the box's voxel that stopped it (within a voxel of the box)
    stops = [m for line in lines if (m := STOPPED.search(line))]
    assert stops, "".join(lines)
    voxel = np.array([float(v) for v in stops[-1].groups()])
    assert np.all(np.abs(voxel - BOX_XYZ) <= BOX_HALF + 0.02), voxel
