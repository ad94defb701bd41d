"""The reference cells of cells/ that several tests run, and the peg cell's probe task."""

from __future__ import annotations

from tests.conftest import ROOT
from tests.rig import write_cell

PALLETIZER = ("cells/palletizer_ur10e.yaml", "tasks/palletize.yaml")


PEG = ("cells/peg_ur3e.yaml", "tasks/peg_insert.yaml")


def probe_task(max_distance_m: float, force_N: float = 8.0) -> str:
    """The peg cell's probe: the empty gripper down from 30 mm above the hole until a force
    over ``force_N`` or ``max_distance_m`` (the block is 30-40 mm down)."""
    return f"""task: probe
steps:
  - move: home
  - approach: {{to: hole, distance: 0.03}}
  - move_until_contact: {{direction: [0, 0, 1], speed: 0.01, force: {force_N:g}, max_distance: {max_distance_m:g}}}
  - retreat: 0.05
  - move: home
"""


PALLET_CELL = (ROOT / PALLETIZER[0]).read_text()
PALLET_TASK = (ROOT / PALLETIZER[1]).read_text()
CARTON = "  - {name: carton, box: {size: [0.20, 0.15, 0.10]}, mass: 2.0, at: infeed}\n"


def place_failed_mm(out: dict) -> float:
    """The offset (mm) a result-3 message measured."""
    assert out["result_code"] == 3, (out["result_text"], out["steps"])
    text = out["result_text"]
    assert text.startswith("place failed: part ") and "from its target (tolerance 5 mm" in text
    return float(text.split(" is ")[1].split(" mm")[0])


def project(tmp_path, cell: str, task: str | None = None) -> tuple[str, str]:
    """``cell`` and ``task`` (default the palletizer's) laid out under ``tmp_path``: their paths."""
    cell_path, task_path = write_cell(tmp_path, cell, PALLET_TASK if task is None else task)
    return str(cell_path), str(task_path)
