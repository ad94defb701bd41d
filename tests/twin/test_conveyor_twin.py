"""Conveyor tracking through the virtual controller (SPEC section 13): `cellrunner twin`
counts the belt's encoder in its pulse decoder as a UR controller does, the photo-eye is a
digital input, and `run --backend ur` (the unmodified ur_rtde client) tracks a part off
the reference belt into the tray."""

from __future__ import annotations

import itertools
import json
import socket
import threading
import time

import numpy as np
import pytest

from cellrunner.backends.ur_conveyor import TICK_REGISTER, setup_program
from tests.rig import fault, run_ur, twin, wait_moving

CELL, TASK = "cells/conveyor_pick_ur10e.yaml", "tasks/conveyor_pick.yaml"
HOST = "127.0.0.163"
#: the reference belt: 0.30 m/s (its speed_max), 4000 ticks/m, a block every 8 s
TICKS_PER_S = 0.30 * 4000
TRAY_PART_XYZ = (0.35, 0.55, 0.826)  # the block's centre once placed (the grip frame)


@pytest.fixture(scope="module")
def belt_twin():
    with twin(CELL, HOST):
        yield HOST


def _wait_for_a_block_at_the_eye(host: str, timeout_s: float = 10.0) -> bool:
    """Watch DI0 (the photo-eye) over RTDE until a block crosses it: True; False after
    ``timeout_s``."""
    import rtde_receive

    receive = rtde_receive.RTDEReceiveInterface(host, 500.0, ["actual_digital_input_bits"])
    try:
        was_on = True
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            on = bool(receive.getActualDigitalInputBits() & 1)
            if on and not was_on:
                return True
            was_on = on
            time.sleep(0.001)
        return False
    finally:
        receive.disconnect()


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


def test_a_tracked_pick_through_ur_rtde_on_the_twin_ends_0_with_the_block_in_the_tray(
    belt_twin,
):
    # the line stands still until the arm waits over the belt (however long the job takes
    # to start on a loaded machine; a block the eye latched long before the arm is there
    # would be let go, 109), then runs at its speed_max again
    assert _wait_for_a_block_at_the_eye(belt_twin)
    fault(belt_twin, "belt belt speed 0")
    result: dict[str, dict[str, object]] = {}
    job = threading.Thread(target=lambda: result.update(out=run_ur(CELL, TASK, belt_twin)))
    job.start()
    try:
        assert wait_moving(belt_twin, 300, ended=lambda: not job.is_alive())
        _wait_still(belt_twin, 0.3, 60)
    finally:
        fault(belt_twin, "belt belt speed 0.3")
    job.join(400)
    out = result["out"]
    assert (out["backend"], out["result_code"]) == ("ur", 0), out["result_text"]
    steps = out["steps"]
    assert isinstance(steps, list)
    assert [s["status"] for s in steps] == ["ok"] * len(steps)
    parts = fault(belt_twin, "parts")
    placed = [
        name
        for name, xyz in json.loads(parts).items()
        if np.linalg.norm(np.subtract(xyz, TRAY_PART_XYZ)) < 0.01
    ]
    assert len(placed) == 1, parts
