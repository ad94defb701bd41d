"""The virtual controller for arms beyond the demo's (SPEC section 11), through the
unmodified ur_rtde client: its controller rate, its model, and a cell's
``robot.joint_range`` as the controller's joint limits. Hosts 127.0.0.190-199."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rtde_control
import rtde_receive

from cellrunner.model.robots import ROBOTS
from tests.twin.twin_process import Dashboard, TwinProcess

RANGE = [[-170, 170], [-180, 0], [-160, 160], [-270, 90], [-180, 0], [-180, 180]]
MODELS = ["ur20", "ur8long", "ur10", "ur3", "ur15", "ur18", "ur30", "ur7e", "ur12e"]
CASES = [(model, f"127.0.0.{190 + k}") for k, model in enumerate(MODELS)]


@pytest.mark.parametrize(("model", "host"), CASES)
def test_twin_runs_the_model_at_its_rate_within_its_joint_range(model, host):
    spec = ROBOTS[model].narrowed(RANGE)
    with TwinProcess(spec, host=host) as twin:
        d = Dashboard(twin.host)
        try:
            assert d.ask("get robot model") == model.upper().removesuffix("E")
        finally:
            d.close()
        receive = rtde_receive.RTDEReceiveInterface(twin.host)
        control = rtde_control.RTDEControlInterface(twin.host)
        try:
            stamps = set()
            t_end = time.monotonic() + 0.3
            while time.monotonic() < t_end:
                stamps.add(round(receive.getTimestamp(), 4))
                time.sleep(0.0005)
            assert np.median(np.diff(sorted(stamps))) == pytest.approx(1 / spec.rate_hz, abs=1e-6)
            q = list(np.radians([10, -80, 80, -90, -90, 20]))
            assert control.isJointsWithinSafetyLimits(q)
            assert control.moveJ(q, 1.0, 2.0)
            assert np.allclose(receive.getActualQ(), q, atol=1e-4)
            outside = list(q)
            outside[5] = np.radians(200)  # wrist 3 beyond the cell's +180 deg
            assert not control.isJointsWithinSafetyLimits(outside)
            outside = list(q)
            outside[1] = np.radians(10)  # shoulder above the cell's 0 deg
            assert not control.isJointsWithinSafetyLimits(outside)
        finally:
            control.disconnect()
            receive.disconnect()
