"""The UR10e jaw picks check approved and the twin stopped (issue 33): the arm's shoulder
could not brake at the controller's 40 rad/s^2, overshot the pick's descend by 15-19 mm
and put the open pads into the infeed table (100, protective stop). check now times every
motion within the joints' torques (planning/dynamics.py); this is bench/cellgen.py's s208
(a UR10e on the ceiling) as it was generated when it stopped in its grip."""

from __future__ import annotations

import shutil
from pathlib import Path

from bench.agreement import cli

#: the cell and task as written then
DATA = Path(__file__).resolve().parent.parent / "data" / "generated" / "s208-ur10e"


def test_a_ur10e_jaw_pick_check_approves_is_rehearsed_without_a_stop(tmp_path):
    shutil.copytree(DATA, tmp_path, dirs_exist_ok=True)  # its plans and journal go there
    cell, task = str(tmp_path / "cell.yaml"), str(tmp_path / "task.yaml")
    code, checked = cli("check", cell, task, "--no-cache")
    assert (code, checked["ok"]) == (0, True), checked
    code, run = cli("dry-run", cell, task)
    assert (run["result_code"], run["result_text"]) == (0, "OK"), run["result_text"]
    # the shoulder follows its set-points: it overshot 15 mm at the descend's end before
    assert run["max_tracking_error_m"] < 0.005
    assert abs(run["cycle_time_s"] - checked["cycle_time_s"]) < 0.3
