"""A gamepad that is unplugged while it moves the arm: `JogSession` against `cellrunner
twin` through ur_rtde, the pad replayed from recorded evdev events on a clock (LB held,
left stick pushed), then the device gone (ENODEV): the session ends with InputLost and the
arm stands still."""

from __future__ import annotations

import errno
import io
import json
import os
import time

import numpy as np
import pytest

from cellrunner.commissioning.inputs import InputLost
from cellrunner.commissioning.inputs import gamepad as gp
from tests.commissioning.conftest import fault, twin, write_project

HOST = f"127.26.{os.getpid() % 250 + 1}.3"


class TimedPad:
    """Recorded events, each released at its time (s after the first read); unplugged at
    ``unplug_s``."""

    path = "/dev/input/event-recorded"

    def __init__(self, events: list[tuple[float, int, int, int]], unplug_s: float) -> None:
        import evdev

        self.evdev, self.events, self.unplug_s = evdev, list(events), unplug_s
        self.t0: float | None = None

    def read_one(self):
        now = time.monotonic()
        self.t0 = self.t0 if self.t0 is not None else now
        if now - self.t0 >= self.unplug_s:
            raise OSError(errno.ENODEV, "No such device")
        if self.events and now - self.t0 >= self.events[0][0]:
            _, type_, code, value = self.events.pop(0)
            return self.evdev.InputEvent(0, 0, type_, code, value)
        return None

    def absinfo(self, code):
        return self.evdev.AbsInfo(0, -32768, 32767, 16, 128, 0)

    def close(self):
        pass


def test_unplugging_the_gamepad_stops_the_arm(tmp_path):
    pytest.importorskip("evdev")
    from cellrunner.commissioning.jog_session import JogSession
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    cell, _ = write_project(tmp_path)
    world = CellWorld(load_cell(cell))
    events = [(0.2, gp.EV_KEY, gp.BTN_TL, 1), (0.2, gp.EV_ABS, gp.ABS_X, 32767)]
    pad = gp.GamepadInput(mode="base", device=TimedPad(events, unplug_s=1.2))
    with twin(cell, HOST):
        q0 = np.array(json.loads(fault(HOST, "state"))["q_rad"])
        session = JogSession(world, HOST, pad, out=io.StringIO(), screen=False)
        session.connect()
        try:
            with pytest.raises(InputLost, match="unplugged; the arm was stopped"):
                session.run()
        finally:
            session.close()
        q_end = np.array(json.loads(fault(HOST, "state"))["q_rad"])
        time.sleep(0.3)
        q_later = np.array(json.loads(fault(HOST, "state"))["q_rad"])
    tcp = world.kinematics.p_world_tcp
    moved = np.linalg.norm(tcp(q_end) - tcp(q0))
    assert moved > 0.05, f"the stick moved the arm {moved * 1000:.0f} mm (1 s at 25 % of 0.25 m/s)"
    assert np.linalg.norm(tcp(q_later) - tcp(q_end)) < 1e-4, "the arm stands after the unplug"
