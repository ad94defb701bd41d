"""Second-release task features in the model (SPEC section 11): params with units and
pose params, quantities with units everywhere, pulses, on_error, place confirm, the
cell's sim: block and place_tolerance; the exact text of their messages."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cellrunner.errors import InputError
from cellrunner.model import geometry
from cellrunner.model.expand import (
    ON_ERROR,
    box_params,
    expand,
    expand_on_error,
    frame_pose,
    resolve_params,
)
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.params import Param
from tests.conftest import DEMO_CELL

CELL_EXTRA = """
sim:
  inputs:
    part_present: {part_at: infeed}
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def task(tmp_path: Path, text: str):
    return load_task(write(tmp_path, "t.yaml", text), load_cell(DEMO_CELL))


def errors(tmp_path: Path, text: str) -> list[str]:
    with pytest.raises(InputError) as exc:
        task(tmp_path, text)
    return [d.message for d in exc.value.diagnostics]


def test_float_param_with_a_unit_reads_its_bounds_in_that_unit_and_stands_for_a_quantity(tmp_path):
    t = task(
        tmp_path,
        """task: t
params:
  dwell: {type: float, unit: ms, min: 50, max: 2000, default: 250}
  clearance: {type: float, unit: mm, min: 20, max: 150, default: 80}
steps:
  - wait: dwell
  - pick: {at: infeed, approach: clearance}
  - wait: "200 ms"
  - set_output: {beacon: true, pulse: "0.3 s"}
""",
    )
    p = t.task.params["dwell"]
    assert (p.min, p.max, p.default) == (0.05, 2.0, 0.25)
    params = resolve_params(t.task, {"dwell": "1.5 s", "clearance": 0.12})
    assert params == {"dwell": 1.5, "clearance": 0.12}
    steps = expand(t, load_cell(DEMO_CELL).cell, params)
    assert steps[0].args.seconds == 1.5
    approach = steps[1]
    assert approach.T_world_tcp[2, 3] == pytest.approx(
        frame_pose(load_cell(DEMO_CELL).cell, "infeed")[2, 3] + 0.12
    )
    assert [s.name for s in steps][-2:] == ["0.2 s", "beacon=True"]
    assert steps[-1].args.pulse == 0.3
    # the default stands where no value is given
    assert expand(t, load_cell(DEMO_CELL).cell, resolve_params(t.task, {}))[0].args.seconds == 0.25


def test_a_param_of_the_wrong_quantity_is_refused_where_it_is_used(tmp_path):
    lines = errors(
        tmp_path,
        """task: t
params:
  dwell: {type: float, unit: s, min: 0.1, max: 2, default: 1}
steps:
  - pick: {at: infeed, approach: dwell}
""",
    )
    assert lines == [
        "steps[0].pick.approach: cannot read '1.0 s' as a length; write a number with one of the "
        "units m, cm, mm, e.g. '500 mm'"
    ]


def test_a_param_bound_outside_what_the_step_accepts_is_refused(tmp_path):
    lines = errors(
        tmp_path,
        """task: t
params:
  pulse_len: {type: float, unit: ms, min: 0, max: 500, default: 100}
steps:
  - set_output: {beacon: true, pulse: pulse_len}
""",
    )
    assert lines == ["steps[0].set_output.pulse: must be > 0 s, got 0 s"]


def test_param_unit_and_value_messages():
    with pytest.raises(ValueError, match=r"^param 'dwell' = 3 s is outside \[0.1, 2\] s$"):
        Param(type="float", unit="s", min=0.1, max=2, default=1).coerce("dwell", "3 s")
    with pytest.raises(Exception, match="unknown unit 'parsec'; known: s, ms, min, m, cm, mm, m/s"):
        Param(type="float", unit="parsec", default=1)
    with pytest.raises(Exception, match="only float params take a unit, not int params"):
        Param(type="int", unit="mm", default=1)


def test_pose_param_box_corners_centre_and_values():
    p = Param(type="pose", min=[-0.05, -0.02, 0, 0, 0, -30], max=[0.05, 0.02, 0, 0, 0, 30])
    assert p.default == {"xyz": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]}
    box = p.box_values()
    assert len(box) == 1 + 8  # x, y and rz vary
    assert box[0] == p.default
    assert {"xyz": [0.05, -0.02, 0.0], "rpy": [0.0, 0.0, -30.0]} in box
    assert p.coerce("pose", '{"xyz": [0.01, 0, 0], "rpy": [0, 0, 10]}') == {
        "xyz": [0.01, 0.0, 0.0],
        "rpy": [0.0, 0.0, 10.0],
    }
    assert p.coerce("pose", {"xyz": ["10 mm", 0, 0]})["xyz"] == [0.01, 0.0, 0.0]
    with pytest.raises(ValueError, match=r"^param 'pose' rz = 40 deg is outside \[-30, 30\] deg$"):
        p.coerce("pose", {"rpy": [0, 0, 40]})
    with pytest.raises(
        ValueError, match=r"^param 'pose' must be a pose \{\"xyz\": \[x, y, z\], \"rpy\": "
    ):
        p.coerce("pose", 3)
    with pytest.raises(Exception, match="a pose param needs min and max"):
        Param(type="pose")


POSE_TASK = """task: t
params:
  seen: {type: pose, min: [-0.03, -0.03, 0, 0, 0, -20], max: [0.03, 0.03, 0, 0, 0, 20]}
steps:
  - pick: {at: {frame: infeed, offset: seen}, approach: 0.1}
  - place: {at: pallet, approach: 0.1, confirm: part_present}
"""


def test_pick_at_a_pose_param_is_the_frame_moved_in_its_own_axes(tmp_path):
    t = task(tmp_path, POSE_TASK)
    cell = load_cell(DEMO_CELL).cell
    seen = {"xyz": [0.02, -0.01, 0.0], "rpy": [0.0, 0.0, 15.0]}
    steps = expand(t, cell, resolve_params(t.task, {"seen": seen}))
    descend = steps[1]
    expected = frame_pose(cell, "infeed") @ geometry.pose_matrix(seen["xyz"], seen["rpy"])
    np.testing.assert_allclose(descend.T_world_tcp, expected, atol=1e-12)
    assert descend.name == "infeed+seen"
    assert list(box_params(t)) == ["seen"] and len(box_params(t)["seen"]) == 9
    release = next(s for s in steps if s.kind == "release")
    assert release.args.confirm == "part_present"
    retreat = steps[-1]
    check = retreat.extra["place_check"]
    assert check["tolerance"] == (0.005, 5.0)
    np.testing.assert_allclose(check["T_world_tcp"], frame_pose(cell, "pallet"))


def test_offset_refers_to_a_pose_param(tmp_path):
    lines = errors(
        tmp_path,
        """task: t
params:
  n: {type: int, min: 0, max: 3, default: 0}
steps:
  - pick: {at: {frame: infeed, offset: n}}
  - pick: {at: {frame: infeed, offset: nope}}
""",
    )
    assert lines == [
        "steps[0].pick.at.offset: offset param 'n' must be of type pose, not int",
        "steps[1].pick.at.offset: unknown param 'nope'; known: n",
    ]
    assert errors(tmp_path, "task: t\nsteps:\n  - pick: {at: {frame: infeed, where: 1}}\n") == [
        "steps[0].pick: 'at' is a frame name or {frame: FRAME, offset: POSE_PARAM}; got keys ['frame', 'where']"
    ]


def test_on_error_steps_are_checked_and_expanded_after_the_task(tmp_path):
    t = task(
        tmp_path,
        """task: t
steps:
  - move: home
  - wait: 0.5
on_error:
  - set_output: {beacon: false}
  - retreat: 0.03
  - move: home
""",
    )
    cell = load_cell(DEMO_CELL).cell
    cleanup = expand_on_error(t, cell, {}, 3)
    assert [(s.index, s.kind, s.macro) for s in cleanup] == [
        (3, "set_output", ON_ERROR),
        (4, "retreat", ON_ERROR),
        (5, "move", ON_ERROR),
    ]
    assert errors(
        tmp_path, "task: t\nsteps: [{move: home}]\non_error:\n  - set_output: {door: false}\n"
    ) == ["on_error[0].set_output.door: unknown output 'door'; known: gripper_close, beacon"]
    assert errors(
        tmp_path, "task: t\nsteps: [{move: home}]\non_error:\n  - place: {at: pallet}\n"
    ) == [
        "on_error[0].place: unknown step 'place'; known: move, approach, descend, linear, lift, retreat, grip, "
        "release, set_output, wait_input, wait, move_until_contact, insert (on_error takes primitive steps)"
    ]


def test_sim_block_and_place_tolerance_in_the_cell(tmp_path):
    text = (
        Path(DEMO_CELL).read_text()
        + """place_tolerance: {distance: "2 mm", angle: 3}
sim:
  inputs:
    part_present: {part_at: infeed}
    gripper_closed: {follows: beacon, delay: "300 ms"}
"""
    )
    cell = load_cell(write(tmp_path, "c.yaml", text)).cell
    assert (cell.place_tolerance.distance, cell.place_tolerance.angle) == (0.002, 3.0)
    assert cell.sim.inputs["gripper_closed"].delay == 0.3
    bad = (
        Path(DEMO_CELL).read_text()
        + """sim:
  inputs:
    door_open: {follows: door_cmd}
    part_present: {part_at: infed}
    beacon: {pulse_after: gripper_close, delay: 1}
    gripper_closed: {follows: beacon, part_at: infeed}
"""
    )
    with pytest.raises(InputError) as exc:
        load_cell(write(tmp_path, "c.yaml", bad))
    lines = [d.message for d in exc.value.diagnostics]
    assert lines == [
        "sim.inputs.gripper_closed: an input rule needs exactly one of part_at, follows, pulse_after; "
        "got part_at, follows"
    ]
    bad = bad.replace("    gripper_closed: {follows: beacon, part_at: infeed}\n", "")
    with pytest.raises(InputError) as exc:
        load_cell(write(tmp_path, "c.yaml", bad))
    lines = [d.message for d in exc.value.diagnostics]
    assert lines == [
        "sim.inputs.door_open: unknown input 'door_open'; known: gripper_closed, part_present",
        "sim.inputs.door_open.follows: unknown output 'door_cmd'; known: gripper_close, beacon",
        "sim.inputs.part_present.part_at: unknown frame 'infed' (did you mean 'infeed'?); known: infeed, pallet",
        "sim.inputs.beacon: 'beacon' is an output, not an input; known inputs: gripper_closed, part_present",
    ]


def test_wait_accepts_units_and_refuses_other_quantities(tmp_path):
    t = task(tmp_path, "task: t\nsteps:\n  - wait: '200 ms'\n  - wait: {seconds: '1.5 min'}\n")
    assert [s.args.seconds for s in t.steps] == [0.2, 90.0]
    assert errors(tmp_path, "task: t\nsteps:\n  - wait: '20 mm'\n") == [
        "steps[0].wait.seconds: cannot read '20 mm' as a time; write a number with one of the units s, ms, min, "
        "e.g. '1.5 s'"
    ]
    assert math.isclose(task(tmp_path, "task: t\nsteps:\n  - wait: 0\n").steps[0].args.seconds, 0.0)


@pytest.mark.parametrize(
    ("kind", "value", "message"),
    [
        ("int", 10**1000, "param 'p' must be a finite number, got one of 1001 digits"),
        ("int", 10**5000, "param 'p' must be a finite number, got one of 5001 digits"),
        ("int", "1" + "0" * 1000, "param 'p' must be a finite number, got inf"),
        ("float", "1e999", "param 'p' must be a finite number, got inf"),
        ("float", float("nan"), "param 'p' must be a finite number, got nan"),
    ],
    ids=["1001_digits", "5001_digits", "1001_digit_text", "1e999", "nan"],
)
def test_a_number_no_param_can_hold_is_refused_not_overflowed(kind, value, message):
    """A PLC's or a command line's 1000-digit number is bad params (11 / exit 2), never an
    OverflowError."""
    with pytest.raises(ValueError) as err:
        Param(type=kind, min=0, max=11, default=0).coerce("p", value)
    assert str(err.value) == message
