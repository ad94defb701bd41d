"""Interlocked pallet layers (SPEC section 13): ``layers``/``layer_pitch`` and ``turn``,
layer k turned by turn[k % len(turn)] deg about the frame's Z, its grid re-laid in the
turned axes (issue 33)."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest
from pydantic import ValidationError

from cellrunner.cli.main import main
from cellrunner.model.expand import expand
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.pattern import Pattern
from tests.conftest import DEMO_CELL

TURNED = (
    "{grid: [2, 1], pitch: [0.06, 0.05], layers: 3, layer_pitch: 0.04, turn: [0, 90], index: slot}"
)
TASK = f"""task: stack
params:
  slot: {{type: int, min: 0, max: 5, default: 0}}
steps:
  - move: home
  - approach: {{to: pallet, distance: 0.05, pattern: {TURNED}}}
  - move: home
"""


def test_layers_and_layer_pitch_stack_as_a_third_grid_entry_does():
    a = Pattern.model_validate(
        {"grid": [2, 1], "pitch": [0.06, 0.05], "layers": 3, "layer_pitch": 0.04, "index": "s"}
    )
    b = Pattern.model_validate({"grid": [2, 1, 3], "pitch": [0.06, 0.05, 0.04], "index": "s"})
    assert a.slots == b.slots == 6
    for slot in range(6):
        assert a.offset_m(slot) == pytest.approx(b.offset_m(slot))
        assert np.allclose(a.T_frame_slot(slot), b.T_frame_slot(slot))


def test_each_odd_layer_turns_a_quarter_and_lays_its_rows_along_the_turned_x():
    p = Pattern.model_validate(
        {
            "grid": [2, 1],
            "pitch": [0.06, 0.05],
            "layers": 3,
            "layer_pitch": 0.04,
            "turn": [0, 90],
            "index": "s",
        }
    )
    assert [p.turn_deg(k) for k in range(3)] == [0.0, 90.0, 0.0]
    assert np.allclose(p.T_frame_slot(1)[:3, 3], [0.06, 0, 0])  # layer 0, row 1
    T = p.T_frame_slot(3)  # layer 1, row 1: 60 mm along the turned X, the frame's Y
    assert np.allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    assert np.allclose(T[:3, 3], [0, 0.06, 0], atol=1e-12)
    assert p.offset_m(3)[2] == pytest.approx(0.04)


@pytest.mark.parametrize(
    "extra, message",
    [
        (
            {"grid": [2, 1, 2], "pitch": [0.06, 0.05, 0.04], "layers": 2, "layer_pitch": 0.04},
            "give the layers once",
        ),
        ({"layers": 2}, "layers need a layer_pitch"),
        ({"layer_pitch": 0.04}, "layer_pitch needs layers"),
    ],
)
def test_layers_given_twice_or_half_are_refused(extra, message):
    with pytest.raises(ValidationError, match=message):
        Pattern.model_validate({"grid": [2, 1], "pitch": [0.06, 0.05], "index": "s", **extra})


def test_a_turned_layer_turns_the_target_about_the_frame_z(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(TASK)
    cell = load_cell(DEMO_CELL)
    task = load_task(path, cell)
    pallet = cell.cell.frames["pallet"].matrix()
    flat = expand(task, cell.cell, {"slot": 1})[1].T_world_tcp
    turned = expand(task, cell.cell, {"slot": 3})[1].T_world_tcp
    # the same row, one layer up, turned 90 deg about the frame's Z
    R_turn = pallet[:3, :3].T @ turned[:3, :3] @ np.linalg.inv(pallet[:3, :3].T @ flat[:3, :3])
    assert np.allclose(R_turn, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-9)
    row_flat = pallet[:3, :3].T @ (flat[:3, 3] - pallet[:3, 3])
    assert turned[2, 3] - flat[2, 3] == pytest.approx(0.04)
    row_turned = pallet[:3, :3].T @ (turned[:3, 3] - pallet[:3, 3] - [0, 0, 0.04])
    assert np.allclose(row_flat[:2] @ [1, 0], 0.06) and np.allclose(
        row_turned[:2], [0, 0.06], atol=1e-9
    )


def test_a_slot_range_past_the_layers_names_them(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(TASK.replace("max: 5", "max: 6"))
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["validate", str(DEMO_CELL), str(path)]) == 2
    assert "does not fit the 2 x 1 x 3 pattern's slots 0..5" in err.getvalue()
