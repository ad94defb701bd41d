"""``pattern`` on any step that takes a frame target (issue 24: it worked on pick and
place only, so four screw holes needed four hand-made frames)."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from cellrunner.cli.main import main
from cellrunner.model.expand import expand
from cellrunner.model.load import load_cell, load_task
from tests.conftest import DEMO_CELL
from tests.rig import json_of

HOLES = "{grid: [2, 2], pitch: [0.05, 0.06], index: hole}"
TASK = f"""task: screws
params:
  hole: {{type: int, min: 0, max: 3, default: 0}}
steps:
  - move: home
  - approach: {{to: pallet, distance: 0.05, pattern: {HOLES}}}
  - descend: {{to: pallet, offset: [0, 0, -0.01], pattern: {HOLES}}}
  - retreat: 0.05
  - move: {{to: pallet, offset: [0, 0, -0.1], pattern: {HOLES}}}
  - move: home
"""


def test_each_hole_of_a_pattern_offsets_every_targeted_step(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(TASK)
    cell = load_cell(DEMO_CELL)
    task = load_task(path, cell)
    pallet = cell.cell.frames["pallet"].matrix()
    steps = expand(task, cell.cell, {"hole": 3})  # row 1, column 1
    expected = pallet[:3, 3] + pallet[:3, :3] @ np.array([0.05, 0.06, -0.01])
    descend = steps[2]
    assert descend.name == "pallet[hole=3]"
    assert np.allclose(descend.T_world_tcp[:3, 3], expected)
    assert steps[1].name == steps[4].name == "pallet[hole=3]"


def test_check_proves_every_hole(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(TASK)
    out = json_of("check", str(DEMO_CELL), str(path), "--no-cache")
    assert out["ok"], out["errors"]
    assert out["slots_checked"] == {"hole": [0, 1, 2, 3]}


def test_a_pattern_on_a_joint_target_is_a_located_error(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(
        TASK.replace("  - move: home\n", f"  - move: {{to: home, pattern: {HOLES}}}\n", 1)
    )
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["validate", str(DEMO_CELL), str(path)]) == 2
    assert "t.yaml:5:" in err.getvalue(), err.getvalue()
    assert (
        "error: steps[0].move.pattern: a pattern offsets a frame; this move's target is not one"
        in err.getvalue()
    )
