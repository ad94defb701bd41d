"""The reference belt cell with its encoder counted by the PLC (``source: plc``), in a
test's own folder: tests/execution/test_plc_encoders.py, tests/plc/test_plc_encoders_serve.py,
tests/twin/test_plc_encoder_on_run.py."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import ROOT

UR_ENCODER = "encoder: {source: ur, index: 0, ticks_per_m: 4000}"


def plc_belt_project(folder: Path, register: int = 20, extra: str = "") -> tuple[Path, Path]:
    """``folder/cells/c.yaml`` (the reference belt cell, its encoder in PLC registers
    ``register``-``register + 1``, ``extra`` appended) and ``folder/tasks/conveyor_pick.yaml``."""
    (folder / "cells").mkdir()
    (folder / "tasks").mkdir()
    text = (ROOT / "cells" / "conveyor_pick_ur10e.yaml").read_text()
    assert UR_ENCODER in text
    plc = f"encoder: {{source: plc, register: {register}, ticks_per_m: 4000}}"
    cell = folder / "cells" / "c.yaml"
    cell.write_text(text.replace(UR_ENCODER, plc) + extra)
    task = folder / "tasks" / "conveyor_pick.yaml"
    task.write_text((ROOT / "tasks" / "conveyor_pick.yaml").read_text())
    return cell, task
