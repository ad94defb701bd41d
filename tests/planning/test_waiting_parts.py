"""Parts waiting at their frames are obstacles for check, except where a grip is meant to
touch them, and the jaws must open wider than the part (issue 24: check agrees with the
twin, whose parts stand there and whose jaws land on a part too wide for them)."""

from __future__ import annotations

import numpy as np

from cellrunner.model.load import load_cell
from cellrunner.planning.world import CellWorld
from tests.conftest import DEMO_CELL
from tests.rig import json_of

#: two poses 12 cm either side of the block waiting at the infeed, at its height
SWEEP = """task: t
steps:
  - move: home
  - move: {{to: infeed, offset: [0.12, 0, 0]}}
  - {kind}: {{to: infeed, offset: [-0.12, 0, 0]}}
  - move: home
"""


def test_a_straight_line_through_a_waiting_part_is_refused(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(SWEEP.format(kind="linear"))
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert not out["ok"]
    assert out["errors"][0].startswith("step 3 linear 'infeed': tool 'jaw_")
    assert "too close to waiting part 'block'" in out["errors"][0]


def test_a_joint_move_goes_around_a_waiting_part(tmp_path):
    """The straight joint move between the two poses sweeps an open jaw through the block;
    the planned move goes around it."""
    task = tmp_path / "t.yaml"
    task.write_text(SWEEP.format(kind="move"))
    world = CellWorld(load_cell(str(DEMO_CELL)))
    kin = world.kinematics
    infeed = world.loaded.cell.frames["infeed"].matrix()
    ends = []
    for dx in (0.12, -0.12):
        T = infeed.copy()
        T[:3, 3] += infeed[:3, :3] @ np.array([dx, 0.0, 0.0])
        ends.append(kin.ik_nearest(T, world.q_home_rad))
    direct = world.collision.check_motion(*ends)
    assert not direct.ok and direct.clearance is not None
    assert direct.clearance.b == "waiting part 'block'"
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert out["ok"], out["errors"]


def test_jaws_narrower_than_the_part_are_refused(tmp_path):
    cell = tmp_path / "narrow.yaml"
    cell.write_text(DEMO_CELL.read_text().replace("stroke: 0.085", "stroke: 0.045"))
    task = tmp_path / "t.yaml"
    task.write_text("task: t\nsteps:\n  - move: home\n  - pick: {at: infeed}\n  - move: home\n")
    out = json_of("check", str(cell), str(task), "--no-cache")
    assert out["errors"] == [
        "step 4 grip 'infeed': part 'block' is 50.0 mm across the jaws (along the TCP's X) "
        "but they open 45.0 mm (tool.gripper.stroke); fix: a gripper with a longer stroke, "
        "or grip the part across a narrower side (turn the frame's rpy about its Z)"
    ]


def test_the_pick_touches_its_waiting_part_and_carries_it_away(tmp_path):
    """The jaws reach around the block (within clearance of it), and once gripped the
    block is carried, no longer waiting: the lift is no collision with its own place."""
    task = tmp_path / "t.yaml"
    task.write_text("task: t\nsteps:\n  - move: home\n  - pick: {at: infeed}\n  - move: home\n")
    out = json_of("check", str(DEMO_CELL), str(task), "--no-cache")
    assert out["ok"], out["errors"]


def test_jaws_around_a_short_block_may_come_down_to_its_table(tmp_path):
    """A 40 mm block: the open pads reach about 2 mm above the table when the TCP is at
    its middle, inside the 2 mm clearance. They may touch the fixture the block rests on
    (picking) or is set on (placing), as the part itself may (issue 24, from the cells
    written from the SPEC: every block under about 45 mm was refused)."""
    cell = tmp_path / "short.yaml"
    cell.write_text(
        DEMO_CELL.read_text()
        .replace("size: [0.05, 0.05, 0.05]", "size: [0.04, 0.04, 0.04]")
        .replace("infeed: {xyz: [0.45, -0.35, 0.925]", "infeed: {xyz: [0.45, -0.35, 0.92]")
    )
    task = tmp_path / "t.yaml"
    task.write_text(
        "task: t\nsteps:\n  - move: home\n  - pick: {at: infeed}\n"
        "  - place: {at: pallet, offset: [0, 0, 0.005]}\n  - move: home\n"
    )
    out = json_of("check", str(cell), str(task), "--no-cache")
    assert out["ok"], out["errors"]


def test_a_bare_grip_carries_the_part_waiting_at_the_tcp_through_check():
    """A bare ``grip`` (no pick macro) takes the part waiting where the TCP stands; carried
    20 mm up and along the belt, it runs into the next box waiting there (the spec-written
    ceiling conveyor cell; before, check carried nothing and approved the sweep)."""
    root = DEMO_CELL.parent.parent / "tests" / "cells" / "spec_written"
    out = json_of(
        "check",
        str(root / "cells" / "ceiling_conveyor_ur5e.yaml"),
        str(root / "tasks" / "conveyor_sweep.yaml"),
        "--no-cache",
    )
    assert not out["ok"]
    assert out["errors"][0].startswith(
        "step 6 linear 'upstream': part 'box' is too close to waiting part 'next_box'"
    )
