"""Commissioning tests: a cell project on disk and `cellrunner twin` in its own process on
a fixed loopback address (127.0.0.150-159), driven through the unmodified ur_rtde client."""

from __future__ import annotations

from pathlib import Path

from tests.rig import cli, fault, twin

__all__ = ["CELL", "TASK", "cli", "fault", "twin", "write_project"]

CELL = """\
cell: commissioning-cell   # a UR10e on a bench
robot:
  model: ur10e
  backend: ur
  mount: {xyz: [0, 0, 0.8], rpy: [0, 0, 180]}   # base turned to face -X of the world
  home: [0, -90, 90, -90, -90, 0]
  limits: {joint_speed: 110, joint_accel: 400, tcp_speed: 1.2, margin: 0.9}
tool:
  tcp: {xyz: [0, 0, 0.17]}          # nominal, from the drawing
  payload: {mass: 1.5, cog: [0, 0, 0.06]}
  geometry: [{cylinder: {radius: 0.045, length: 0.1}, xyz: [0, 0, 0.05]}]
io:
  outputs: {jaws: TO0}
  inputs: {jaws_closed: TI0}
fixtures:
  - {name: bench, box: {size: [1.6, 1.2, 0.05]}, pose: {xyz: [0.5, 0, 0.775]}}
  - {name: wall, box: {size: [0.05, 1.2, 1.0]}, pose: {xyz: [1.05, 0, 1.3]}}

# named targets, measured with a tape
frames:
  pick: {xyz: [0.7, -0.4, 0.83], rpy: [180, 0, 45]}   # infeed
  drop:   {xyz: [0.7, 0.4, 0.835], rpy: [180, 0, 0]}   # keep: hand aligned
tasks: {1: tasks/t.yaml}
"""

TASK = """\
task: short_moves
steps:
  - approach: {to: pick, distance: 0.1}
  - descend: {to: pick}
  - lift: {distance: 0.1}
  - move: home
"""


def write_project(root: Path, cell: str = CELL, task: str = TASK) -> tuple[Path, Path]:
    (root / "cells").mkdir(parents=True, exist_ok=True)
    (root / "tasks").mkdir(exist_ok=True)
    (root / "cells" / "c.yaml").write_text(cell)
    (root / "tasks" / "t.yaml").write_text(task)
    return root / "cells" / "c.yaml", root / "tasks" / "t.yaml"
