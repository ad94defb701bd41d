"""Suction places verified in the twin (SPEC section 11): a part released off its target
(off the pallet, in the air above an empty layer, onto another part) gives 3 with the
measured offset, never 0; a part pressed onto another one stops the arm. Run on the
palletizer and on a second, smaller vacuum cell written from the SPEC alone."""

from __future__ import annotations

import pytest

from tests.cells.reference import CARTON, PALLET_CELL, PALLET_TASK, PALLETIZER, project
from tests.rig import dry_run


def fixed_place(z_m: float) -> tuple[str, str]:
    """The palletizer's cell with a frame ``z_m`` above slot 0, and its task placing there
    (no pattern: no earlier slots are filled)."""
    frame = f"  high_slot0: {{xyz: [0.69, 0.285, {0.24 + z_m:g}], rpy: [180, 0, 0]}}\n"
    cell = PALLET_CELL.replace("frames:\n", "frames:\n" + frame)
    task = PALLET_TASK.replace(
        "at: pallet_slot0\n      pattern: {grid: [2, 2, 3], pitch: [0.22, 0.17, 0.10], index: slot}",
        "at: high_slot0",
    )
    assert "high_slot0" in task
    return cell, task


def test_an_upper_layer_slot_rehearsed_alone_stacks_on_the_earlier_slots():
    """SPEC section 12: slot 4 (layer 2) rehearsed with slots 0-3 in place, where the task
    puts them: the carton lands on the slot-0 carton."""
    out = dry_run(*PALLETIZER, "-p", "slot=4")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["carton"][2] == pytest.approx(0.29, abs=0.003)
    assert sorted(p for p in out["parts_end_m"] if "@" in p) == [
        f"carton@slot={k}" for k in range(4)
    ]


def test_palletizer_carton_released_above_an_empty_layer_is_refused_before_it_moves(tmp_path):
    """Layer 2 over an empty slot 0, at a frame of its own (no pattern, nothing filled
    before it): the twin measured the 100 mm fall (3) until check knew a placed part must
    rest on something (issue 24)."""
    out = dry_run(*project(tmp_path, *fixed_place(0.10)))
    assert out["result_code"] == 103, out["result_text"]
    assert out["result_text"].startswith(
        "step 9 release 'high_slot0': the part 'carton' would be let go with nothing under it"
    )


def test_palletizer_carton_released_off_the_pallet_is_refused_before_it_moves(tmp_path):
    """1 cm of the carton on the pallet, its centre over the floor: it tipped off in the
    twin (3) before check knew that a placed part must rest on something (issue 24)."""
    wide = PALLET_TASK.replace("pitch: [0.22, 0.17, 0.10]", "pitch: [0.22, 0.40, 0.10]")
    out = dry_run(*project(tmp_path, PALLET_CELL, wide), "-p", "slot=1")
    assert out["result_code"] == 103, out["result_text"]
    assert out["result_text"].startswith(
        "step 9 release 'pallet_slot0[slot=1]': the part 'carton' would be let go with "
        "nothing under it within place_tolerance 5 mm"
    )


@pytest.fixture(scope="module")
def stacked(tmp_path_factory) -> tuple[str, str]:
    """The palletizer with a carton already on slot 0 of the first layer."""
    stock = CARTON + CARTON.replace("carton", "stock").replace("infeed", "pallet_slot0")
    return project(tmp_path_factory.mktemp("stacked"), PALLET_CELL.replace(CARTON, stock))


def test_a_carton_stacked_on_another_is_placed(stacked):
    out = dry_run(*stacked, "-p", "slot=4")  # layer 2, on the stock carton
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["carton"][2] == pytest.approx(0.29, abs=0.003)


def test_the_third_layer_on_two_stacked_cartons_is_placed(tmp_path):
    """The pallet as two earlier jobs left it (slots 0 and 4): slot 8 goes on top."""
    stock = CARTON + "".join(
        CARTON.replace("carton", name).replace(
            "at: infeed}", f"at: pallet_slot0, offset: {{xyz: [0, 0, {-0.10 * k:g}]}}}}"
        )
        for k, name in enumerate(("layer1", "layer2"))
    )
    out = dry_run(*project(tmp_path, PALLET_CELL.replace(CARTON, stock)), "-p", "slot=8")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["carton"][2] == pytest.approx(0.39, abs=0.003)  # layer 3


def test_the_earlier_slots_a_cell_file_already_fills_are_left_as_they_are(stacked):
    """Slot 8 (layer 3) with the stock carton on slot 0: slots 1-7 are filled, slot 0 keeps
    the stock."""
    out = dry_run(*stacked, "-p", "slot=8")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["carton"][2] == pytest.approx(0.39, abs=0.003)
    assert sorted(p for p in out["parts_end_m"] if "@" in p) == [
        f"carton@slot={k}" for k in range(1, 8)
    ]


def test_a_carton_released_onto_another_a_layer_low_is_refused_before_it_moves(tmp_path):
    stock = CARTON + CARTON.replace("carton", "stock").replace("infeed", "pallet_slot0")
    cell, task = fixed_place(0.20)  # layer 3 over the stock, layer 2 empty
    out = dry_run(*project(tmp_path, cell.replace(CARTON, stock), task))
    assert out["result_code"] == 103, out["result_text"]
    assert "let go with nothing under it" in out["result_text"]


def test_a_carton_pressed_onto_another_is_refused_before_it_moves(stacked):
    """Slot 0 is taken by the stock carton: the descend would push the carton 100 mm into
    it. The stock carton waits at its frame, an obstacle check knows of, so the job is
    refused before it starts (the twin's protective stop, 100, before issue 24)."""
    out = dry_run(*stacked, "-p", "slot=0")
    assert out["result_code"] == 103, (out["result_text"], out["steps"])
    assert out["result_text"].startswith(
        "step 8 descend 'pallet_slot0[slot=0]': at its end the part 'carton' would be "
        "100.0 mm inside waiting part 'stock'"
    )


def test_an_empty_conveyor_times_out_at_the_part_present_wait(tmp_path):
    away = CARTON.replace("at: infeed}", "at: infeed, offset: {xyz: [0, 0.3, 0]}}")
    out = dry_run(*project(tmp_path, PALLET_CELL.replace(CARTON, away)))
    assert (out["result_code"], out["result_text"]) == (
        105,
        "input part_present did not read True within 5 s",
    )


# a second vacuum cell, written from the SPEC's text alone
SUCTION_CELL = """cell: suction-ur5e
robot:
  model: ur5e
  mount: {xyz: [0, 0, 0.90], rpy: [0, 0, 0]}
  home: [0, -90, 90, -90, -90, 0]
tool:
  tcp: {xyz: [0, 0, 0.12]}
  payload: {mass: 0.8, cog: [0, 0, 0.05]}
  gripper:
    kind: vacuum
    suction: {output: vac, value: true}
    vacuum_ok: vac_ok
    blow_off: {output: blow, pulse: 0.1}
    cups: [{xyz: [0, 0, 0], radius: 0.015}]
    holding_force: 60
  geometry: [{cylinder: {radius: 0.03, length: 0.12}, xyz: [0, 0, 0.06]}]
io:
  outputs: {vac: DO0, blow: DO1}
  inputs: {vac_ok: DI0, part_present: DI1}
fixtures:
  - {name: table, box: {size: [0.6, 0.8, 0.04]}, pose: {xyz: [0.45, 0, 0.88]}}
frames:
  infeed: {xyz: [0.45, -0.25, 0.94], rpy: [180, 0, 0]}
  tray: {xyz: [0.45, 0.25, 0.94], rpy: [180, 0, 0]}
  past_edge: {xyz: [0.78, 0.25, 0.94], rpy: [180, 0, 0]}
  in_the_air: {xyz: [0.45, 0.25, 0.99], rpy: [180, 0, 0]}
parts:
  - {name: lid, box: {size: [0.08, 0.08, 0.04]}, mass: 0.4, at: infeed}
sim:
  inputs:
    part_present: {part_at: infeed}
tasks: {1: tasks/t.yaml}
"""
SUCTION_TASK = """task: move_lid
steps:
  - move: home
  - wait_input: {input: part_present, value: true, timeout: "500 ms"}
  - pick:
      at: infeed
      approach: 0.08
      grip: {confirm: vac_ok, force: {min: 1, max: 20}, timeout: 1}
  - place: {at: tray, approach: 0.08}
  - move: home
"""


def test_second_vacuum_cell_verifies_its_place(tmp_path):
    out = dry_run(*project(tmp_path, SUCTION_CELL, SUCTION_TASK))
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["lid"] == pytest.approx([0.45, 0.25, 0.92], abs=0.002)


@pytest.mark.parametrize(
    "target, nearest",
    # the twin gave 3 for both (the lid fell to the floor, or 50 mm onto the table) before
    # check knew that a placed part must rest on something (issue 24)
    [("past_edge", "fixture 'table'"), ("in_the_air", "fixture 'table'")],
)
def test_a_lid_let_go_over_nothing_is_refused_before_it_moves(tmp_path, target, nearest):
    task = SUCTION_TASK.replace("at: tray", f"at: {target}")
    out = dry_run(*project(tmp_path, SUCTION_CELL, task))
    assert out["result_code"] == 103, (out["result_text"], out["steps"])
    assert (
        f"would be let go with nothing under it within place_tolerance 5 mm (the nearest thing is {nearest}"
        in out["result_text"]
    )
