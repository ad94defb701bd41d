"""Places are judged against the target the task put the part at, never against how the
gripper happened to hold it (SPEC section 11), and faults act on the part actually held,
whatever its size: jaws and suction alike, on parts lying off their frames."""

from __future__ import annotations

import pytest

from tests.cells.reference import (
    CARTON,
    PALLET_CELL,
    PALLET_TASK,
    PALLETIZER,
    place_failed_mm,
    project,
)
from tests.conftest import ROOT
from tests.rig import dry_run

DEMO_CELL = (ROOT / "cells/demo_ur5e.yaml").read_text()
DEMO_TASK = (ROOT / "tasks/pick_place.yaml").read_text()
BLOCK = "  - {name: block, box: {size: [0.05, 0.05, 0.05]}, mass: 0.3, at: infeed}\n"


def demo_with_block(tmp_path, offset: str) -> tuple[str, str]:
    block = BLOCK.replace("at: infeed}", f"at: infeed, offset: {{xyz: {offset}}}}}")
    cell = DEMO_CELL.replace(BLOCK, block).replace("tasks/pick_place.yaml", "tasks/t.yaml")
    return project(tmp_path, cell, DEMO_TASK)


def test_a_block_gripped_off_centre_is_placed_off_its_slot_by_as_much(tmp_path):
    """20 mm off along the frame's Y (the jaws close along X): held off-centre, it lands
    20 mm off its slot, a failed place, whatever the jaws held."""
    out = dry_run(*demo_with_block(tmp_path, "[0, 0.02, 0]"))
    assert place_failed_mm(out) == pytest.approx(20.0, abs=2.5)


def test_a_block_the_jaws_centre_is_placed_on_its_slot(tmp_path):
    """10 mm off along X, the closing jaws push it back to the centre: it lands on its
    slot, and the twin says so."""
    out = dry_run(*demo_with_block(tmp_path, "[0.01, 0, 0]"))
    assert out["result_code"] == 0, (out["result_text"], out["steps"])


def test_a_carton_sealed_off_centre_is_placed_off_its_slot(tmp_path):
    """15 mm off (the conveyor's sensor still sees it at the stop): sealed off-centre,
    stacked 15 mm off its slot."""
    shifted = CARTON.replace("at: infeed}", "at: infeed, offset: {xyz: [0.015, 0, 0]}}")
    out = dry_run(*project(tmp_path, PALLET_CELL.replace(CARTON, shifted)))
    assert place_failed_mm(out) == pytest.approx(15.0, abs=2.0)


# a 200 mm carton: its centre 100 mm under the cups, its top face at the frames
TALL_CELL = (
    PALLET_CELL.replace(
        "size: [0.20, 0.15, 0.10]}, mass: 2.0", "size: [0.20, 0.15, 0.20]}, mass: 3.0"
    )
    .replace("xyz: [0.15, -0.70, 0.70]", "xyz: [0.15, -0.70, 0.80]")
    .replace("xyz: [0.69, 0.285, 0.24]", "xyz: [0.69, 0.285, 0.34]")
)


@pytest.mark.parametrize("fault, code", [(None, 0), ("grip_miss@grip", 1)])
def test_a_tall_carton_is_placed_and_grip_miss_takes_it_away(tmp_path, fault, code):
    inject = ("--inject", fault) if fault else ()
    out = dry_run(*project(tmp_path, TALL_CELL, PALLET_TASK), *inject)
    assert out["result_code"] == code, (out["result_text"], out["steps"])
    if fault:  # moved clear of the cups (more than its half-diagonal plus theirs)
        x, y, _ = out["parts_end_m"]["carton"]
        assert ((x - 0.15) ** 2 + (y + 0.70) ** 2) ** 0.5 > 0.2


def test_the_palletizer_still_places_its_carton(tmp_path):
    out = dry_run(*PALLETIZER)
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
