"""A joint move goes to another IK branch of its goal when no path reaches the nearest
(issue 33): on a wall, the nearest branch of a pick's approach lies where the upper arm
would have to pass through the plate, and the next one is reached."""

from __future__ import annotations

import shutil
from pathlib import Path

from tests.rig import cli_json

#: the agreement harness's s60450 as it was written: a UR5 on a wall, feasible by
#: construction (a witness configuration exists for each frame, and joint paths join them
#: to home)
DATA = Path(__file__).resolve().parent.parent / "data" / "generated" / "s60450-ur5-wall"


def test_a_move_reaches_another_branch_when_no_path_leads_to_the_nearest(tmp_path):
    shutil.copytree(DATA, tmp_path, dirs_exist_ok=True)  # its plans go there
    code, out = cli_json("check", str(tmp_path / "cell.yaml"), str(tmp_path / "task.yaml"))
    assert code == 0, out["errors"]
    approach = next(s for s in out["steps"] if s["kind"] == "approach")
    assert approach["status"] == "ok"
