"""serve's warm-up loads what the first jobs would load lazily, OMPL included (a job that
needs a joint search loaded ~7 MiB of it mid-serve, at whatever job a fault first left
the arm away from a cached start)."""

from __future__ import annotations

import subprocess
import sys

from tests.conftest import ROOT

PROBE = """
import sys
from cellrunner.execution.planner import warm_up
from cellrunner.model.load import load_cell
from cellrunner.planning.world import CellWorld
assert "ompl.geometric" not in sys.modules
warm_up(CellWorld(load_cell(sys.argv[1])))
print(sorted(m for m in ("ompl.base", "ompl.geometric", "ompl.util") if m in sys.modules))
"""


def test_warm_up_loads_ompl() -> None:
    out = subprocess.run(
        [sys.executable, "-c", PROBE, str(ROOT / "cells" / "demo_ur5e.yaml")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split("\n")[-2] == "['ompl.base', 'ompl.geometric', 'ompl.util']"
