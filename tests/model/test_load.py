"""Loading the example files and the exact text of the important messages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cellrunner.errors import InputError
from cellrunner.model.expand import expand, frame_pose, pattern_params, resolve_params
from cellrunner.model.load import load_cell, load_task
from tests.conftest import DEMO_CELL, PICK_PLACE, ROOT


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def errors_of(fn, *args) -> list[str]:
    with pytest.raises(InputError) as exc:
        fn(*args)
    return [str(d) for d in exc.value.diagnostics]


def test_examples_load():
    cell = load_cell(DEMO_CELL)
    assert cell.cell.robot.model == "ur5e"
    for task_path in cell.cell.tasks.values():
        load_task(cell.resolve(task_path), cell)


def test_embedded_examples_are_the_repo_examples():
    embedded = ROOT / "cellrunner" / "examples"
    for p in [DEMO_CELL, *sorted((ROOT / "tasks").glob("*.yaml"))]:
        twin = embedded / p.parent.name / p.name
        assert twin.read_text() == p.read_text(), f"{twin} differs from {p}"


MINIMAL = """cell: c
robot: {model: ur10e, home: [0, -90, 90, -90, -90, 0]}
"""


def test_minimal_cell_gets_defaults(tmp_path):
    cell = load_cell(write(tmp_path, "c.yaml", MINIMAL)).cell
    assert cell.robot.backend == "ur" and cell.robot.limits.margin == 0.95
    assert cell.tool.tcp.xyz == [0, 0, 0]


def test_several_errors_all_reported_in_file_order(tmp_path):
    text = (
        MINIMAL.replace("ur10e", "ur11e")
        + "frames:\n  a: {xyz: [0, 0], rpy: [0, 0, 0]}\nfixtures: 3\n"
    )
    lines = errors_of(load_cell, write(tmp_path, "c.yaml", text))
    assert len(lines) == 3
    assert lines[0].startswith(
        f"{tmp_path}/c.yaml:2:16: error: robot.model: unknown robot model 'ur11e'"
    )
    assert (
        lines[1]
        == f"{tmp_path}/c.yaml:4:12: error: frames.a.xyz: expected at least 3 items in this list, got 2"
    )
    assert lines[2] == f"{tmp_path}/c.yaml:5:11: error: fixtures: expected a list, got 3"


def test_ur10e_speed_cap_is_per_joint(tmp_path):
    text = MINIMAL + "  \n"
    text = text.replace("home:", "limits: {joint_speed: [120, 130, 180, 180, 180, 180]}, home:")
    lines = errors_of(load_cell, write(tmp_path, "c.yaml", text))
    assert lines == [
        f"{tmp_path}/c.yaml:2:51: error: robot.limits.joint_speed[1]: 130 deg/s on joint 2 "
        "(shoulder_lift) is above the UR10E controller's 120 deg/s"
    ]


def test_radians_by_mistake_warns_but_loads(tmp_path):
    text = MINIMAL.replace("[0, -90, 90, -90, -90, 0]", "[0, -1.57, 1.57, -1.57, -1.57, 0]")
    cell = load_cell(write(tmp_path, "c.yaml", text))
    assert [str(w) for w in cell.warnings] == [
        f"{tmp_path}/c.yaml:2:29: warning: robot.home: [0, -1.57, 1.57, -1.57, -1.57, 0] looks like "
        "radians; angles are in degrees (write e.g. '1.57 rad' if you mean radians)"
    ]


def test_units_in_strings(tmp_path):
    text = MINIMAL.replace(
        "home:", "limits: {tcp_speed: '250 mm/s', joint_speed: '1 rad/s'}, home:"
    )
    limits = load_cell(write(tmp_path, "c.yaml", text)).cell.robot.limits
    assert limits.tcp_speed == pytest.approx(0.25)
    assert limits.joint_speed == pytest.approx(57.29577951308232)


def test_pick_place_expansion():
    cell = load_cell(DEMO_CELL)
    task = load_task(PICK_PLACE, cell)
    steps = expand(task, cell.cell, resolve_params(task.task, {"slot": "7"}))
    assert [s.kind for s in steps] == [
        "move",
        "approach",
        "descend",
        "grip",
        "lift",
        "approach",
        "descend",
        "release",
        "retreat",
        "move",
    ]
    assert [s.index for s in steps] == list(range(1, 11))
    grip = steps[3]
    assert grip.retry.attempts == 3 and grip.retry.redo_from == 3
    assert [b.kind for b in grip.retry.between] == ["release", "retreat"]
    # slot 7 -> row 1, col 3 of the 3 x 4 grid: +0.07 along pallet X, +0.21 along pallet Y
    T_pallet = frame_pose(cell.cell, "pallet")
    expected = T_pallet[:3, 3] + T_pallet[:3, 0] * 0.07 + T_pallet[:3, 1] * 0.21
    np.testing.assert_allclose(steps[6].T_world_tcp[:3, 3], expected, atol=1e-12)
    assert steps[6].name == "pallet[slot=7]"
    # the approach point is 0.10 m back along the frame's Z (the frame's Z points down)
    np.testing.assert_allclose(steps[5].T_world_tcp[:3, 3], expected + [0, 0, 0.10], atol=1e-12)
    assert pattern_params(task) == {"slot": range(0, 12)}


def test_params_are_checked():
    cell = load_cell(DEMO_CELL)
    task = load_task(PICK_PLACE, cell)
    with pytest.raises(InputError) as exc:
        resolve_params(task.task, {"slot": 12})
    assert exc.value.diagnostics[0].message == "param 'slot' = 12 is outside [0, 11]"
    with pytest.raises(InputError) as exc:
        resolve_params(task.task, {"slto": 1})
    assert exc.value.diagnostics[0].message == "unknown param 'slto'; known: slot"


def test_frame_parent_chain(tmp_path):
    text = (
        MINIMAL
        + "frames:\n  base: {xyz: [1, 0, 0], rpy: [0, 0, 90]}\n  child: {parent: base, xyz: [1, 0, 0]}\n"
    )
    cell = load_cell(write(tmp_path, "c.yaml", text)).cell
    np.testing.assert_allclose(frame_pose(cell, "child")[:3, 3], [1, 1, 0], atol=1e-12)


def test_short_forms(tmp_path):
    cell = load_cell(DEMO_CELL)
    task = write(
        tmp_path,
        "t.yaml",
        "task: t\nsteps:\n  - move: [0, -90, 90, -90, -90, '0 rad']\n"
        "  - lift: '50 mm'\n  - wait: 0.5\n  - release\n  - approach: infeed\n",
    )
    steps = expand(load_task(task, cell), cell.cell, {})
    assert steps[0].q_goal_deg == (0, -90, 90, -90, -90, 0)
    assert steps[1].args.distance == pytest.approx(0.05)
    assert steps[2].args.seconds == 0.5
    assert steps[3].kind == "release"
    assert steps[4].args.distance == pytest.approx(0.1)
