"""Conveyor tracking through the virtual controller (SPEC section 13): `cellrunner twin`
counts the belt's encoder in its pulse decoder as a UR controller does, the photo-eye is a
digital input, and `run --backend ur` (the unmodified ur_rtde client) tracks a part off
the reference belt into the tray."""

from __future__ import annotations

import itertools
import json
import re
import socket
import threading
import time
from typing import Any

import numpy as np
import pytest

from cellrunner.backends.ur_conveyor import TICK_REGISTER, setup_program
from tests.rig import fault, run_ur, twin, wait_moving

CELL, TASK = "cells/conveyor_pick_ur10e.yaml", "tasks/conveyor_pick.yaml"
HOST, JUMP_HOST = "127.0.0.163", "127.0.0.164"
#: the reference belt: 0.30 m/s (its speed_max), 4000 ticks/m, a block every 8 s
TICKS_PER_S = 0.30 * 4000
TRAY_PART_XYZ = (0.35, 0.55, 0.826)  # the block's centre once placed (the grip frame)


@pytest.fixture(scope="module")
def belt_twin():
    with twin(CELL, HOST):
        yield HOST


def _enable_decoder(host: str) -> None:
    with socket.create_connection((host, 30002), timeout=3.0) as sock:
        sock.sendall(setup_program([0]).encode())


def test_the_twin_counts_encoder_ticks_and_the_eye_is_an_input_read_by_ur_rtde(belt_twin):
    import rtde_receive

    receive = rtde_receive.RTDEReceiveInterface(
        belt_twin,
        500.0,
        ["timestamp", f"output_int_register_{TICK_REGISTER}", "actual_digital_input_bits"],
    )
    try:
        _enable_decoder(belt_twin)
        samples: list[tuple[float, int]] = []
        edges: list[float] = []
        eye_was = None
        deadline = time.monotonic() + 9.0  # a block passes the eye every 8 s
        while time.monotonic() < deadline and len(samples) < 100_000:
            t, ticks = receive.getTimestamp(), receive.getOutputIntRegister(TICK_REGISTER)
            eye = bool(receive.getActualDigitalInputBits() & 1)  # part_at_eye: DI0
            if eye and eye_was is False:
                edges.append(t)
            eye_was = eye
            samples.append((t, ticks))
            time.sleep(0.002)
    finally:
        receive.disconnect()
    counting = [(t, n) for t, n in samples if n != 0]
    assert len(counting) > 100, samples[-5:]
    (t0, n0), (t1, n1) = counting[0], counting[-1]
    assert (n1 - n0) / (t1 - t0) == pytest.approx(TICKS_PER_S, rel=0.02)
    assert all(b[1] >= a[1] for a, b in itertools.pairwise(counting))
    assert edges, "no block crossed the photo-eye within 9 s"


def _wait_still(host: str, still_s: float, timeout_s: float) -> None:
    """Wait until the twin's arm target has not moved for ``still_s``."""
    last, since = None, time.monotonic()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() - since < still_s:
        assert time.monotonic() < deadline, f"the arm did not come to rest within {timeout_s} s"
        target = json.loads(fault(host, "state"))["target_q_rad"]
        if last is None or max(abs(a - b) for a, b in zip(target, last, strict=True)) > 1e-4:
            last, since = target, time.monotonic()
        time.sleep(0.02)


def _run_with_the_line_held(host: str, once_following: str | None = None) -> dict[str, Any]:
    """``run --backend ur`` of the reference task with the line standing still until the
    arm waits over the belt (however long the job takes to start on a loaded machine: a
    block the eye latched long before the arm is there would be let go, 109); then the
    belt runs at its speed_max again and, ``once_following``, that fault-channel command
    is sent 0.3 s after the arm set off after the block."""
    fault(host, "belt belt speed 0")
    result: dict[str, dict[str, Any]] = {}
    job = threading.Thread(target=lambda: result.update(out=run_ur(CELL, TASK, host)))
    job.start()
    try:
        moving = wait_moving(host, 300, ended=lambda: not job.is_alive())
        job.join(0 if moving else 400)
        assert moving, (result["out"]["result_code"], result["out"]["result_text"])
        _wait_still(host, 0.3, 60)
    finally:
        fault(host, "belt belt speed 0.3")
    if once_following is not None:
        moving = wait_moving(host, 30, ended=lambda: not job.is_alive())
        job.join(0 if moving else 400)
        assert moving, (result["out"]["result_code"], result["out"]["result_text"])
        time.sleep(0.3)
        fault(host, once_following)
    job.join(400)
    return result["out"]


def test_a_tracked_pick_through_ur_rtde_on_the_twin_ends_0_with_the_block_in_the_tray(
    belt_twin,
):
    out = _run_with_the_line_held(belt_twin)
    assert (out["backend"], out["result_code"]) == ("ur", 0), out["result_text"]
    steps = out["steps"]
    assert [s["status"] for s in steps] == ["ok"] * len(steps)
    parts = fault(belt_twin, "parts")
    placed = [
        name
        for name, xyz in json.loads(parts).items()
        if np.linalg.norm(np.subtract(xyz, TRAY_PART_XYZ)) < 0.01
    ]
    assert len(placed) == 1, parts


def test_an_encoder_jump_on_the_twin_is_a_controlled_stop_not_a_chase():
    with twin(CELL, JUMP_HOST):  # an arm at home, that the job moves over the belt
        _an_encoder_jump_is_a_controlled_stop(JUMP_HOST)


def _an_encoder_jump_is_a_controlled_stop(belt_twin: str) -> None:
    out = _run_with_the_line_held(belt_twin, once_following="belt belt jump 0.05")
    assert out["result_code"] == 100, out["result_text"]
    # the 50 mm jump, against the speed the encoder measured (0.30 m/s, to its counts)
    jump = re.search(r"belt is \+([0-9.]+) mm off its measured ([0-9.]+) m/s", out["result_text"])
    assert jump is not None, out["result_text"]
    assert 40.0 < float(jump[1]) < 60.0 and abs(float(jump[2]) - 0.300) < 0.005
    assert "controlled stop" in out["result_text"] or "stays where it is" in out["result_text"]
    # the arm stands where it stopped, it does not go after the reading
    before = json.loads(fault(belt_twin, "state"))["target_q_rad"]
    time.sleep(0.5)
    after = json.loads(fault(belt_twin, "state"))["target_q_rad"]
    assert max(abs(a - b) for a, b in zip(before, after, strict=True)) < 1e-4
