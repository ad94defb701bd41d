"""The demo cell's pick with an on_error of a test's own (tests/planning/test_on_error_*.py)."""

from __future__ import annotations

from tests.conftest import ROOT

DEMO = str(ROOT / "cells" / "demo_ur5e.yaml")
PICK = """task: pick_then_home
steps:
  - move: home
  - pick: {at: infeed, approach: 0.1, grip: {confirm: gripper_closed}}
  - move: home
on_error:
"""


def task(tmp_path, on_error: str) -> str:
    path = tmp_path / "t.yaml"
    path.write_text(PICK + on_error)
    return str(path)
