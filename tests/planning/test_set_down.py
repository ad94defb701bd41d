"""A carried part pushed into a fixture: `check` refuses it, allowing only the 1 mm
set-down touch, and the twin never reports OK for it (SPEC section 11)."""

from __future__ import annotations

import pytest

from tests.conftest import DEMO_CELL
from tests.rig import json_of

PLACE = "task: t\nsteps:\n  - move: home\n  - pick: {{at: infeed}}\n  - place: {{at: pallet, offset: [0, 0, {dz}]}}\n"


@pytest.mark.parametrize("dz", ["0.0035", "0"])  # pressed 0.5 mm onto the table, set 3 mm above it
def test_a_set_down_touch_is_approved_and_placed(tmp_path, dz):
    task = tmp_path / "t.yaml"
    task.write_text(PLACE.format(dz=dz))
    assert json_of("check", str(DEMO_CELL), str(task), "--no-cache")["ok"]
    assert json_of("dry-run", str(DEMO_CELL), str(task))["result_code"] == 0


def test_a_part_pushed_into_the_table_is_refused_by_check(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(
        PLACE.format(dz="0.02")
    )  # the pallet frame's Z points down: 17 mm into the table
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert out["errors"] == [
        "step 7 descend 'pallet': at its end the part 'block' would be 17.0 mm inside fixture 'table' (setting a "
        "part down may press 1 mm at most); move the target up by 16.0 mm or more"
    ]
