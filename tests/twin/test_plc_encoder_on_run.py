"""``run --backend ur`` has no PLC: a belt whose encoder the PLC counts (``source: plc``)
is not measured there, and its ``track`` step is refused with 103 naming why, the arm
never set onto the belt (SPEC section 13; ``serve`` reads the PLC's registers:
tests/plc/test_plc_encoders_serve.py). Through the unmodified ur_rtde client against
``cellrunner twin`` of the same cell."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import ROOT
from tests.rig import run_ur, twin

HOST = "127.0.0.174"


def test_run_on_the_arm_refuses_to_track_a_belt_the_plc_counts(tmp_path: Path) -> None:
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    text = (ROOT / "cells" / "conveyor_pick_ur10e.yaml").read_text()
    ur = "encoder: {source: ur, index: 0, ticks_per_m: 4000}"
    assert ur in text
    text = text.replace(ur, "encoder: {source: plc, register: 20, ticks_per_m: 4000}")
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(text)
    task = tmp_path / "tasks" / "conveyor_pick.yaml"
    task.write_text((ROOT / "tasks" / "conveyor_pick.yaml").read_text())
    with twin(cell, HOST):
        out = run_ur(cell, task, HOST)
    assert (out["backend"], out["result_code"]) == ("ur", 103), out["result_text"]
    assert "cannot measure the belt" in out["result_text"], out["result_text"]
    steps = out["steps"]
    # the move over the belt ran; the track step is the one refused, nothing after it ran
    assert steps[0]["status"] == "ok" and steps[1]["status"] != "ok", steps[:3]
    assert all(s["status"] != "ok" for s in steps[1:]), steps
