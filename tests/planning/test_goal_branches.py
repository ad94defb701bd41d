"""A joint move goes to another IK branch of its goal when no path reaches the nearest
(issue 33): on a wall, the nearest branch of a pick's approach lies where the upper arm
would have to pass through the plate, and the next one is reached."""

from __future__ import annotations

from tests.rig import cli_json

#: the agreement harness's s60450: a UR5 on a wall, feasible by construction (a witness
#: configuration exists for each frame, and joint paths join them to home)
CELL = """
cell: gen-60450-feasible
robot:
  model: ur5
  host: 127.0.0.2
  backend: sim
  mount:
    xyz: [0.0, 0.0, 1.4]
    rpy: [0.0, 90.0, 0.0]
  home: [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]
tool:
  tcp:
    xyz: [0, 0, 0.158]
    rpy: [0, 0, 0]
  payload:
    mass: 1.0
    cog: [0, 0, 0.053]
  gripper:
    kind: io
    close: {output: gripper_close, value: true}
    closed_sensor: gripper_closed
    stroke: 0.086
  geometry:
  - cylinder: {radius: 0.058, length: 0.098}
    xyz: [0, 0, 0.049]
io:
  outputs: {gripper_close: DO0}
  inputs: {gripper_closed: DI0}
fixtures:
- name: wall_plate
  box:
    size: [0.02, 0.4, 0.4]
  pose:
    xyz: [-0.02, 0, 1.4]
- name: infeed_table
  box:
    size: [0.3, 0.3, 0.04]
  pose:
    xyz: [0.39118, -0.19366, 1.0422]
- name: outfeed_table
  box:
    size: [0.3, 0.3, 0.04]
  pose:
    xyz: [0.47002, 0.1755, 0.88508]
frames:
  infeed:
    xyz: [0.39118, -0.19366, 1.0977]
    rpy: [180.0, 0.0, -66.9773]
  outfeed:
    xyz: [0.47002, 0.1755, 0.94058]
    rpy: [180.0, 0.0, 11.5421]
parts:
- name: part
  box:
    size: [0.057, 0.043, 0.071]
  mass: 0.77
  at: infeed
tasks: {1: task.yaml}
journal: var/jobs.sqlite
"""

TASK = """
task: pick_place
steps:
- {move: home}
- pick: {at: infeed, approach: 0.08, grip: {confirm: gripper_closed}}
- place: {at: outfeed, approach: 0.08}
- {move: home}
"""


def test_a_move_reaches_another_branch_when_no_path_leads_to_the_nearest(tmp_path):
    (tmp_path / "cell.yaml").write_text(CELL)
    (tmp_path / "task.yaml").write_text(TASK)
    code, out = cli_json("check", str(tmp_path / "cell.yaml"), str(tmp_path / "task.yaml"))
    assert code == 0, out["errors"]
    approach = next(s for s in out["steps"] if s["kind"] == "approach")
    assert approach["status"] == "ok"
