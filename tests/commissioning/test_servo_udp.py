"""`cellrunner jog --input udp:PORT` against `cellrunner twin`, driven by a program that
is not cellrunner (tests/commissioning/udp_sender.py: a raw socket, its own process), the
arm measured through the unmodified ur_rtde receive client in this process."""

from __future__ import annotations

import json
import socket
import time

import numpy as np

from tests.commissioning.conftest import CELL, fault, twin, write_project
from tests.commissioning.servo_rig import HOST, Recorder, jog_udp, send
from tests.rig import free_port

#: a table 0.18 m under the TCP at home (the mount turns the base: base -X, -Y is world +X, +Y)
TABLE = "  - {name: table, box: {size: [0.6, 0.6, 0.04]}, pose: {xyz: [0.69, 0.17, 1.28]}}\n"


def test_a_program_streams_twists_the_arm_follows_then_stops(tmp_path):
    cell, _ = write_project(
        tmp_path, cell=CELL.replace("\n# named targets", TABLE + "\n# named targets")
    )
    port = free_port("127.0.0.1")
    with twin(cell, HOST), jog_udp(cell, port) as (_proc, lines):
        rec = Recorder(HOST)
        try:
            time.sleep(0.3)
            # malformed datagrams are counted and dropped: they never move the arm
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                for bad in (
                    b"not json",
                    b"[1, 2]",
                    b'{"seq": 1, "twist": [0.05, 0, 0, 0, 0]}',
                    b'{"seq": 2, "twist": [0.05, 0, 0, 0, 0, NaN]}',
                    b'{"seq": true, "twist": [0.05, 0, 0, 0, 0, 0]}',
                    b'{"seq": 3, "frame": "world", "twist": [0.05, 0, 0, 0, 0, 0]}',
                ):
                    sock.sendto(bad, ("127.0.0.1", port))
            time.sleep(0.3)
            sent = send(port, "0.05,0,0:1.0")  # +X of the base, 50 mm/s for 1 s
            time.sleep(0.8)
            t, p = rec.arrays()
            before = p[t < sent["first_s"]]
            assert np.ptp(before, axis=0).max() < 1e-5, "malformed datagrams moved the arm"
            moved = np.linalg.norm(p - p[0], axis=1)
            start = t[np.argmax(moved > 2e-4)]
            travel = moved[-1]
            assert 0.030 <= travel <= 0.060, travel
            assert start - sent["first_s"] < 0.050, f"started {start - sent['first_s']:.3f} s late"
            direction = (p[-1] - p[0]) / travel
            assert direction[0] > 0.99, direction  # along base +X
            still = p[t > sent["last_s"] + 0.3]
            assert len(still) > 50 and np.ptp(still, axis=0).max() < 1e-5, "still moving"
            # a push down toward the table for 6 s stops above it; the safety mode stays normal
            z0 = p[-1][2]
            send(port, "0,0,-0.05:6.0")
            time.sleep(0.5)
            state = json.loads(fault(HOST, "state"))
            assert state["safety_mode"] == "NORMAL"
            z = rec.arrays()[1][-1][2]
            assert z0 - z > 0.03, "it went down"
            assert any("fixture 'table'" in line for line in lines), "".join(lines[-20:])
            from cellrunner.model.load import load_cell
            from cellrunner.planning.world import CellWorld

            collision = CellWorld(load_cell(cell)).collision
            distances, _ = collision.pair_distances(np.array(state["q_rad"]))
            to_table = [
                d
                for d, (a, b) in zip(distances, collision.pair_labels, strict=True)
                if "'table'" in a + b
            ]
            assert 0.0 < min(to_table) < 0.12, "stopped above the table, near it"
        finally:
            rec.close()
    summary = lines[-1]
    assert "6 malformed" in summary, summary
