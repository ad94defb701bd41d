"""A peg 20 mm across into a square hole with walls a given gap away (SPEC section 12
tight fits): the cell and task texts the tight-fit tests write."""

from __future__ import annotations

from pathlib import Path

WALLS = ("wall_xm", "wall_xp", "wall_ym", "wall_yp")


def peg_cell(gap_m: float) -> str:
    """A UR3e cell whose hole (centred at x 0.30, y 0.15, 40 mm deep on the table) is
    20 mm + 2 ``gap_m`` wide: its walls are ``gap_m`` from a centred 20 mm peg."""
    w, t, cx, cy = 0.020 + 2 * gap_m, 0.03, 0.30, 0.15
    walls = [
        ("wall_xm", (cx - w / 2 - t / 2, cy), (t, w + 2 * t)),
        ("wall_xp", (cx + w / 2 + t / 2, cy), (t, w + 2 * t)),
        ("wall_ym", (cx, cy - w / 2 - t / 2), (w, t)),
        ("wall_yp", (cx, cy + w / 2 + t / 2), (w, t)),
    ]
    fixtures = "".join(
        f"  - {{name: {n}, box: {{size: [{s[0]:.4f}, {s[1]:.4f}, 0.04]}}, "
        f"pose: {{xyz: [{c[0]:.4f}, {c[1]:.4f}, 0.82]}}}}\n"
        for n, c, s in walls
    )
    return f"""cell: tight-peg
robot:
  model: ur3e
  host: 127.0.0.2
  backend: sim
  mount: {{xyz: [0, 0, 0.80], rpy: [0, 0, 180]}}
  home: [0, -90, 90, -90, -90, 0]
  limits: {{joint_speed: 120, joint_accel: 300, tcp_speed: 0.5, margin: 0.9}}
tool:
  tcp: {{xyz: [0, 0, 0.14]}}
  payload: {{mass: 0.9, cog: [0, 0, 0.05]}}
  gripper: {{kind: io, close: {{output: jaws, value: true}}, closed_sensor: jaws_closed, stroke: 0.05, close_time: 0.15}}
  geometry: [{{cylinder: {{radius: 0.035, length: 0.09}}, xyz: [0, 0, 0.045]}}]
io:
  outputs: {{jaws: TO0}}
  inputs: {{jaws_closed: TI0}}
fixtures:
  - {{name: table, box: {{size: [0.8, 0.8, 0.04]}}, pose: {{xyz: [0.25, 0, 0.78]}}}}
{fixtures}  - {{name: hole_floor, box: {{size: [{w:.4f}, {w:.4f}, 0.01]}}, pose: {{xyz: [0.30, 0.15, 0.805]}}}}
frames:
  peg_feed: {{xyz: [0.25, -0.15, 0.85], rpy: [180, 0, 0]}}
  hole: {{xyz: [0.30, 0.15, 0.89], rpy: [180, 0, 0]}}
parts:
  - {{name: peg, cylinder: {{radius: 0.01, length: 0.10}}, mass: 0.05, at: peg_feed}}
tasks: {{1: task.yaml}}
"""


def peg_task(descend: str = "", insert: str = "") -> str:
    """Pick the peg, stop 30 mm above the hole, descend to its mouth and insert 25 mm;
    ``descend`` and ``insert`` are extra arguments of those steps (", contact: [...]")."""
    return f"""task: tight_peg
steps:
  - move: home
  - pick: {{at: peg_feed, approach: 0.08, grip: {{confirm: jaws_closed}}}}
  - approach: {{to: hole, distance: 0.03}}
  - descend: {{to: hole{descend}}}
  - insert: {{to: hole, depth: 0.025, speed: 0.01, force: {{max: 10}}, expect_depth: [0.022, 0.026]{insert}}}
  - release
  - retreat: 0.08
  - move: home
"""


def write(tmp: Path, gap_m: float, descend: str = "", insert: str = "") -> tuple[str, str]:
    cell, task = tmp / "cell.yaml", tmp / "task.yaml"
    cell.write_text(peg_cell(gap_m))
    task.write_text(peg_task(descend, insert))
    return str(cell), str(task)
