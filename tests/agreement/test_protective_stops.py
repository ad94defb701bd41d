"""The UR10e jaw picks check approved and the twin stopped (issue 33): the arm's shoulder
could not brake at the controller's 40 rad/s^2, overshot the pick's descend by 15-19 mm
and put the open pads into the infeed table (100, protective stop). check now times every
motion within the joints' torques (planning/dynamics.py); this is bench/cellgen.py's s208
(a UR10e on the ceiling) as it was generated when it stopped in its grip."""

from __future__ import annotations

from bench.agreement import cli

CELL = """\
cell: gen-208-feasible
robot:
  model: ur10e
  host: 127.0.0.2
  backend: sim
  mount:
    xyz: [0.0, 0.0, 2.0]
    rpy: [180.0, 0.0, 0.0]
  home: [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]
tool:
  tcp:
    xyz: [0, 0, 0.154]
    rpy: [0, 0, 0]
  payload:
    mass: 1.0
    cog: [0, 0, 0.051]
  gripper:
    kind: io
    close: {output: gripper_close, value: true}
    closed_sensor: gripper_closed
    stroke: 0.083
  geometry:
  - cylinder: {radius: 0.057, length: 0.094}
    xyz: [0, 0, 0.047]
io:
  outputs: {gripper_close: DO0}
  inputs: {gripper_closed: DI0}
fixtures:
- name: ceiling_plate
  box:
    size: [0.4, 0.4, 0.02]
  pose:
    xyz: [0, 0, 2.02]
- name: infeed_table
  box:
    size: [0.3, 0.3, 0.04]
  pose:
    xyz: [0.35139, -0.89923, 1.14818]
- name: outfeed_table
  box:
    size: [0.3, 0.3, 0.04]
  pose:
    xyz: [0.38776, 0.55074, 1.22867]
frames:
  infeed:
    xyz: [0.35139, -0.89923, 1.20418]
    rpy: [180.0, 0.0, -78.2583]
  outfeed:
    xyz: [0.38776, 0.55074, 1.28467]
    rpy: [-180.0, 0.0, 108.83]
parts:
- name: part
  box:
    size: [0.047, 0.056, 0.072]
  mass: 0.57
  at: infeed
tasks: {1: task.yaml}
journal: var/jobs.sqlite
"""

TASK = """\
task: pick_place
steps:
- {move: home}
- pick:
    at: infeed
    approach: 0.08
    grip: {confirm: gripper_closed}
- place: {at: outfeed, approach: 0.08}
- {move: home}
"""


def test_a_ur10e_jaw_pick_check_approves_is_rehearsed_without_a_stop(tmp_path):
    (tmp_path / "cell.yaml").write_text(CELL)
    (tmp_path / "task.yaml").write_text(TASK)
    cell, task = str(tmp_path / "cell.yaml"), str(tmp_path / "task.yaml")
    code, checked = cli("check", cell, task, "--no-cache")
    assert (code, checked["ok"]) == (0, True), checked
    code, run = cli("dry-run", cell, task)
    assert (run["result_code"], run["result_text"]) == (0, "OK"), run["result_text"]
    # the shoulder follows its set-points: it overshot 15 mm at the descend's end before
    assert run["max_tracking_error_m"] < 0.005
    assert abs(run["cycle_time_s"] - checked["cycle_time_s"]) < 0.3
