"""Input errors of several tools, the tool changer, vacuum grippers and the force steps:
one located line each, naming the bad value and the valid ones."""

from __future__ import annotations

import subprocess
import sys

from tests.cells.two_tools import CELL, TASK
from tests.conftest import ROOT


def validate(tmp_path, cell: str, task: str | None = None) -> subprocess.CompletedProcess:
    (tmp_path / "c.yaml").write_text(cell)
    args = [str(tmp_path / "c.yaml")]
    if task is not None:
        (tmp_path / "t.yaml").write_text(task)
        args.append(str(tmp_path / "t.yaml"))
    return subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "validate", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )


def test_two_tools_validate(tmp_path):
    r = validate(tmp_path, CELL, TASK)
    assert r.returncode == 0, r.stderr


def test_unknown_mounted_tool_names_the_tools(tmp_path):
    r = validate(tmp_path, CELL.replace("  tool: jaws\n", "  tool: jawz\n"))
    assert r.returncode == 2
    assert r.stderr.strip() == (
        f"{tmp_path}/c.yaml:7:9: error: robot.tool: unknown tool 'jawz' "
        "(did you mean 'jaws'?); known: jaws, cup"
    )
    assert "Traceback" not in r.stderr


def test_change_tool_to_an_unknown_tool(tmp_path):
    r = validate(tmp_path, CELL, TASK.replace("change_tool: cup", "change_tool: gripper"))
    assert r.returncode == 2
    assert r.stderr.strip() == (
        f"{tmp_path}/t.yaml:4:18: error: steps[1].change_tool: unknown tool 'gripper'; "
        "known: jaws, cup"
    )


def test_rack_missing_a_tool(tmp_path):
    r = validate(
        tmp_path, CELL.replace("rack: {jaws: rack_jaws, cup: rack_cup}", "rack: {jaws: rack_jaws}")
    )
    assert r.returncode == 2
    assert r.stderr.strip() == (
        f"{tmp_path}/c.yaml:28:9: error: tool_changer.rack: the rack has no place for "
        "tool(s) 'cup'; give each a frame: rack: {jaws: FRAME, cup: FRAME}"
    )


def test_rack_frame_unknown(tmp_path):
    r = validate(tmp_path, CELL.replace("cup: rack_cup}", "cup: rack_cups}"))
    assert r.returncode == 2
    assert (
        "tool_changer.rack.cup: unknown frame 'rack_cups' (did you mean 'rack_cup'?); known: rack_jaws, "
        "rack_cup, spot, touch" in r.stderr
    )


def test_vacuum_gripper_needs_its_suction(tmp_path):
    cell = CELL.replace("      suction: {output: vacuum_on}\n", "")
    r = validate(tmp_path, cell)
    assert r.returncode == 2
    assert r.stderr.strip().endswith(
        "error: tools.cup.gripper: a vacuum gripper needs 'suction: {output, value}'"
    )


def test_vacuum_ok_must_be_an_input(tmp_path):
    r = validate(tmp_path, CELL.replace("vacuum_ok: vacuum_ok", "vacuum_ok: vacuum_on"))
    assert r.returncode == 2
    assert (
        "tools.cup.gripper.vacuum_ok: 'vacuum_on' is an output, not an input; known inputs: jaws_closed, "
        "vacuum_ok, tool_locked" in r.stderr
    )


def test_force_step_errors(tmp_path):
    task = TASK.replace(
        "  - move: spot\n",
        "  - insert: {to: spott, depth: 0.02, force: {max: 10}}\n"
        "  - move_until_contact: {direction: [0, 0, 0], max_distance: 0.05}\n",
    )
    r = validate(tmp_path, CELL, task)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert any(
        line.endswith(
            "error: steps[3].move_until_contact.direction: direction [0, 0, 0] has no length; "
            "e.g. [0, 0, 1] (tool Z)"
        )
        for line in lines
    ), lines
    r = validate(
        tmp_path,
        CELL,
        TASK.replace(
            "  - move: spot\n", "  - insert: {to: spott, depth: 0.02, force: {max: 10}}\n"
        ),
    )
    assert r.stderr.strip().endswith(
        "error: steps[2].insert.to: unknown frame 'spott' (did you mean 'spot'?); "
        "known: rack_jaws, rack_cup, spot, touch"
    )


def test_task_must_end_with_its_start_tool(tmp_path):
    r = validate(tmp_path, CELL, TASK.replace("  - change_tool: jaws\n", ""))
    assert r.returncode == 2
    assert r.stderr.strip() == (
        f"{tmp_path}/t.yaml:4:18: error: steps[1].change_tool: the task ends with tool 'cup' "
        "mounted, but every job starts with 'jaws' (robot.tool); add 'change_tool: jaws' "
        "before the end"
    )
