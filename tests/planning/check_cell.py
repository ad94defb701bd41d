"""A small cell and a pick-and-place task for ``check`` tests, and ``check`` run on them."""

from __future__ import annotations

import subprocess
from pathlib import Path

from tests.rig import cli

CELL = """
cell: test-cell
robot:
  model: ur5e
  mount: {xyz: [0, 0, 0.9], rpy: [0, 0, 180]}
  home: [0, -90, 90, -90, -90, 0]
  limits: {joint_speed: 100, joint_accel: 250, tcp_speed: 0.8, margin: 0.9}
tool:
  tcp: {xyz: [0, 0, 0.15]}
  gripper: {kind: io, close: {output: close, value: true}, closed_sensor: closed}
  geometry: [{cylinder: {radius: 0.04, length: 0.09}, xyz: [0, 0, 0.045]}]
io:
  outputs: {close: DO0}
  inputs: {closed: DI0}
fixtures:
  - {name: table, box: {size: [1.2, 0.9, 0.04]}, pose: {xyz: [0.4, 0, 0.88]}}
  - {name: wall, box: {size: [0.3, 0.02, 0.25]}, pose: {xyz: [0.5, 0.0, 1.025]}}
  - {name: block, box: {size: [0.06, 0.06, 0.18]}, pose: {xyz: [0.35, 0.25, 0.98]}}
frames:
  a: {xyz: [0.45, -0.25, 0.923], rpy: [180, 0, 0]}   # the part 3 mm above the table
  b: {xyz: [0.45, 0.25, 0.923], rpy: [180, 0, 0]}
  over_block: {xyz: [0.35, 0.25, 0.93], rpy: [180, 0, 0]}
  far_away: {xyz: [1.9, 0.0, 1.0], rpy: [180, 0, 0]}
  grid: {xyz: [0.30, -0.45, 0.95], rpy: [180, 0, 0]}
parts:
  - {name: p, box: {size: [0.04, 0.04, 0.04]}, mass: 0.2, at: a}
"""

PICK_PLACE = """task: t
steps:
  - move: home
  - pick: {at: a, approach: 0.1, grip: {confirm: closed}}
  - place: {at: b, approach: 0.1}
  - move: home
"""


def check(cell: Path, task: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """``cellrunner check CELL TASK --json EXTRA`` in a child process."""
    return cli("check", str(cell), str(task), "--json", *extra)
