"""Float params are proved over their whole range, as pose boxes are: the range's ends and
centre are planned, and a value that fails is named (issue 24: a float param was proved
at its default only, and `-p side=0.85` then failed a job check had called feasible)."""

from __future__ import annotations

from tests.conftest import DEMO_CELL
from tests.rig import json_of

TASK = """task: t
params:
  high: {type: float, unit: mm, min: 50, max: MAX, default: 100}
  dwell: {type: float, unit: s, min: 0, max: 5, default: 0.5}
steps:
  - move: home
  - pick: {at: infeed, approach: high}
  - wait: dwell
  - move: home
"""


def test_every_end_of_a_float_range_is_proved(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(TASK.replace("MAX", "200"))
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert out["ok"], out["errors"]
    # the approach height at its ends and centre; a wait's time changes no motion
    assert out["slots_checked"] == {"high": [0.05, 0.125, 0.2]}


def test_a_float_value_out_of_reach_is_refused_with_the_value(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(TASK.replace("MAX", "900"))
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert not out["ok"]
    assert [e.split(":")[0] for e in out["errors"]] == ["high=0.9"]
    assert out["errors"][0].startswith("high=0.9: step 2 approach 'infeed': ")
