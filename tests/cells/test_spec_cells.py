"""Cells written from SPEC section 11's text alone (no reference cell copied), through
``validate``, ``check`` and ``dry-run``: each found a gap that is fixed and pinned here.

- force steps, float params with units given as plain SI numbers on the command line, a
  pulse output read back through a ``follows`` rule, ``place_tolerance``: the retreat
  after a ``move_until_contact`` whose line ends past the contact was refused (the
  set-down rule outranked the contact the force step allowed);
- two tools (robotiq jaws, a two-cup vacuum tool) on a changer, the part picked by the
  tool mounted second: it was spawned as the start tool holds parts (centred, so it fell
  5 cm), its ``part_at`` sensor never saw it, and the cups pressing on the part they hold
  were judged a finger landing on a part; ``place: {confirm}`` by a ``part_at`` sensor.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cellrunner.cli.main import main
from tests.cells.reference import project
from tests.rig import main_json

PRESS_CELL = """cell: press-fit
robot:
  model: ur3e
  mount: {xyz: [0, 0, 0.8], rpy: [0, 0, 0]}
  home: [0, -90, 90, -90, -90, 0]
tool:
  tcp: {xyz: [0, 0, 0.14]}
  payload: {mass: 0.6, cog: [0, 0, 0.04]}
  gripper:
    kind: io
    close: {output: close, value: true}
    closed_sensor: closed
    stroke: 0.04
  geometry: [{cylinder: {radius: 0.03, length: 0.1}, xyz: [0, 0, 0.05]}]
io:
  outputs: {close: DO0, light: DO2}
  inputs: {closed: DI0, seated: DI3}
place_tolerance: {distance: "3 mm", angle: 3}
fixtures:
  - {name: bench, box: {size: [0.5, 0.5, 0.04]}, pose: {xyz: [0.25, 0, 0.78]}}
  - {name: block, box: {size: [0.08, 0.08, 0.03]}, pose: {xyz: [0.25, 0.12, 0.815]}}
frames:
  pin_nest: {xyz: [0.25, -0.12, 0.845], rpy: [180, 0, 0]}
  block_top: {xyz: [0.25, 0.12, 0.89], rpy: [180, 0, 0]}
parts:
  - {name: pin, cylinder: {radius: 0.006, length: 0.08}, mass: 0.02, at: pin_nest}
sim:
  inputs:
    seated: {follows: light, delay: 0.2}
tasks: {1: tasks/t.yaml}
"""
PRESS_TASK = """task: touch
params:
  push: {type: float, unit: N, min: 2, max: 30, default: 10}
  dwell: {type: float, unit: s, min: 0, max: 2, default: "300 ms"}
  reach: {type: float, unit: m, min: 0.05, max: 0.055, default: "51 mm"}  # touches at 50 mm
steps:
  - move: home
  - pick: {at: pin_nest, approach: 0.05, grip: {confirm: closed, force: {min: 0.05, max: 5}, timeout: 1}}
  - approach: {to: block_top, distance: 0.03}
  - move_until_contact: {direction: [0, 0, -1], frame: world, speed: 0.01, force: push, max_distance: reach}
  - wait: dwell
  - set_output: {light: true, pulse: "250 ms"}
  - wait_input: {input: seated, value: true, timeout: "0.5 s"}
  - wait: "200 ms"
  - retreat: 0.05
  - move: home
"""
TOOLS_CELL = """cell: two-tool-cell
robot:
  model: ur10e
  mount: {xyz: [0, 0, 0.0], rpy: [0, 0, 0]}
  home: [0, -90, 90, -90, -90, 0]
  tool: jaws
tools:
  jaws:
    tcp: {xyz: [0, 0, 0.16]}
    payload: {mass: 1.2, cog: [0, 0, 0.05]}
    gripper:
      kind: robotiq
      stroke: 0.085
    geometry: [{cylinder: {radius: 0.04, length: 0.12}, xyz: [0, 0, 0.06]}]
  suction:
    tcp: {xyz: [0, 0, 0.20]}
    payload: {mass: 0.9, cog: [0, 0, 0.08]}
    gripper:
      kind: vacuum
      suction: {output: vac_on, value: true}
      vacuum_ok: vac_ok
      blow_off: {output: blow, pulse: 0.05}
      cups: [{xyz: [0.03, 0, 0], radius: 0.015}, {xyz: [-0.03, 0, 0], radius: 0.015}]
      holding_force: 80
    geometry: [{box: {size: [0.1, 0.05, 0.18]}, xyz: [0, 0, 0.09]}]
tool_changer:
  lock: changer_lock
  locked: changer_locked
  rack: {jaws: rack_a, suction: rack_b}
io:
  outputs: {vac_on: DO0, blow: DO1, changer_lock: DO2}
  inputs: {vac_ok: DI0, changer_locked: DI1, box_here: DI2, box_placed: DI3}
fixtures:
  - {name: table, box: {size: [1.0, 1.4, 0.04]}, pose: {xyz: [0.6, 0, -0.02]}}
frames:
  rack_a: {xyz: [0.5, 0.45, 0.15], rpy: [180, 0, 0]}
  rack_b: {xyz: [0.65, 0.45, 0.15], rpy: [180, 0, 0]}
  pickup: {xyz: [0.6, -0.3, 0.1], rpy: [180, 0, 0]}
  dropoff: {xyz: [0.6, 0.1, 0.1], rpy: [180, 0, 0]}
parts:
  - {name: box, box: {size: [0.12, 0.08, 0.1]}, mass: 0.5, at: pickup}
sim:
  inputs:
    box_here: {part_at: pickup}
    box_placed: {part_at: dropoff}
tasks: {1: tasks/t.yaml}
"""
#: a pose param from a camera, an insert, a release confirmed by a part_at sensor, on_error
#: with a release, and the SPEC's own sim: example (the cycle pulse goes unused)
CAM_CELL = """cell: cam-insert
robot:
  model: ur5e
  mount: {xyz: [0, 0, 0.9], rpy: [0, 0, 180]}
  home: [0, -90, 90, -90, -90, 0]
tool:
  tcp: {xyz: [0, 0, 0.15]}
  payload: {mass: 1.0, cog: [0, 0, 0.05]}
  gripper:
    kind: io
    close: {output: grip, value: true}
    closed_sensor: grip_closed
    stroke: 0.05
  geometry: [{cylinder: {radius: 0.035, length: 0.1}, xyz: [0, 0, 0.05]}]
io:
  outputs: {grip: DO0, cnc_start: DO1, door_cmd: DO2}
  inputs: {grip_closed: DI0, part_present: DI1, door_open: DI2, cycle_done: DI3, seated: DI4}
fixtures:
  - {name: table, box: {size: [0.8, 0.8, 0.04]}, pose: {xyz: [0.45, 0, 0.88]}}
  - {name: plate_a, box: {size: [0.04, 0.1, 0.04]}, pose: {xyz: [0.5, 0.25, 0.92]}}
  - {name: plate_b, box: {size: [0.04, 0.1, 0.04]}, pose: {xyz: [0.58, 0.25, 0.92]}}
  - {name: plate_c, box: {size: [0.04, 0.04, 0.04]}, pose: {xyz: [0.54, 0.32, 0.92]}}
  - {name: plate_d, box: {size: [0.04, 0.04, 0.04]}, pose: {xyz: [0.54, 0.18, 0.92]}}
frames:
  infeed: {xyz: [0.45, -0.25, 0.93], rpy: [180, 0, 0]}
  hole: {xyz: [0.54, 0.25, 0.97], rpy: [180, 0, 90]}
parts:
  - {name: plug, box: {size: [0.03, 0.03, 0.06]}, mass: 0.1, at: infeed, offset: {xyz: [0.01, -0.01, 0], rpy: [0, 0, 10]}}
sim:
  inputs:
    part_present: {part_at: infeed, within: 0.03}
    seated: {part_at: hole, within: 0.05}
    door_open: {follows: door_cmd, delay: 1.5}
    cycle_done: {pulse_after: cnc_start, delay: 20, width: 0.5}
tasks: {1: tasks/t.yaml}
"""
CAM_TASK = """task: cam_insert
params:
  seen: {type: pose, min: [-0.02, -0.02, 0, 0, 0, -15], max: [0.02, 0.02, 0, 0, 0, 15], default: {xyz: [0.01, -0.01, 0], rpy: [0, 0, 10]}}
steps:
  - move: home
  - wait_input: {input: part_present, value: true, timeout: 1}
  - pick: {at: {frame: infeed, offset: seen}, approach: 0.1, grip: {confirm: grip_closed, force: {min: 0.3, max: 5}}}
  - approach: {to: hole, distance: 0.05}
  - insert: {to: hole, depth: 0.025, speed: 0.01, force: {max: 15}, expect_depth: [0.02, 0.03]}
  - release: {confirm: seated}
  - retreat: 0.08
  - move: home
on_error:
  - release
  - retreat: 0.05
  - move: home
"""
TOOLS_TASK = """task: swap_and_move
steps:
  - move: home
  - change_tool: suction
  - wait_input: {input: box_here, value: true, timeout: 1}
  - pick: {at: pickup, approach: 0.1, grip: {confirm: vac_ok, timeout: 1}}
  - place: {at: dropoff, approach: 0.1, confirm: box_placed}
  - change_tool: jaws
  - move: home
"""


@pytest.fixture(scope="module")
def press(tmp_path_factory) -> tuple[str, str]:
    return project(tmp_path_factory.mktemp("press"), PRESS_CELL, PRESS_TASK)


@pytest.fixture(scope="module")
def tools(tmp_path_factory) -> tuple[str, str]:
    return project(tmp_path_factory.mktemp("tools"), TOOLS_CELL, TOOLS_TASK)


@pytest.fixture(scope="module")
def cam(tmp_path_factory) -> tuple[str, str]:
    return project(tmp_path_factory.mktemp("cam"), CAM_CELL, CAM_TASK)


@pytest.mark.parametrize("cell", ["press", "tools", "cam"])
def test_spec_cells_validate(request, cell, capsys):
    assert main(["validate", *request.getfixturevalue(cell)]) == 0


def test_press_checks_with_the_retreat_leaving_the_contact(press):
    code, out = main_json("check", *press)
    assert code == 0, out["errors"]
    rows = {s["index"]: s for s in out["steps"]}
    assert rows[7]["kind"] == "move_until_contact"
    assert rows[7]["message"] == (
        "guarded: stops above 10 N; 51 mm line checked; contact allowed with: block"
    )
    assert rows[12]["kind"] == "retreat" and rows[12]["status"] == "ok"


def test_press_runs_in_the_twin(press):
    code, out = main_json("dry-run", *press)
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    rows = {s["index"]: s for s in out["steps"]}
    assert rows[8]["name"] == "0.3 s" and rows[8]["duration_s"] == pytest.approx(0.3, abs=0.01)
    assert rows[9]["duration_s"] == pytest.approx(0.25, abs=0.01)  # the pulse
    assert rows[10]["name"] == "seated" and rows[10]["status"] == "ok"  # follows the pulse


def test_float_params_take_plain_si_numbers_on_the_command_line(press):
    code, out = main_json("dry-run", *press, "-p", "push=25", "-p", "dwell=0", "-p", "reach=0.054")
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    assert out["params"] == {"push": 25.0, "dwell": 0.0, "reach": 0.054}


def test_a_reach_range_that_falls_short_is_refused_with_the_value(press, tmp_path):
    """check proves a float param's whole range (issue 24): a reach of 10 mm falls 40 mm
    short of the block, and 100 mm runs the jaws into it."""
    cell, task = press
    short = tmp_path / "t.yaml"
    short.write_text(
        Path(task).read_text().replace("min: 0.05, max: 0.055", "min: 0.01, max: 0.055")
    )
    code, out = main_json("check", cell, str(short))
    assert code == 1
    assert out["errors"][0].startswith(
        "reach=0.01: step 7 move_until_contact: the guarded line meets nothing within its "
        "max_distance 10 mm: at its end the held part is still 40.0 mm from fixture 'block'"
    )


def test_second_tool_picks_the_part_laid_for_its_cups_and_confirms_the_place(tools):
    code, out = main_json("check", *tools)
    assert code == 0, out["errors"]
    code, out = main_json("dry-run", *tools)
    assert (code, out["result_code"]) == (0, 0), (out["result_text"], out["steps"])
    assert out["parts_end_m"]["box"] == pytest.approx([0.6, 0.1, 0.05], abs=0.003)


def test_camera_pose_insert_and_confirmed_release(cam):
    code, out = main_json("check", *cam)
    assert code == 0, out["errors"]
    assert len(out["slots_checked"]["seen"]) == 9  # the pose box's centre and corners
    assert [s["message"] for s in out["steps"][-3:]] == [
        # mid-move states too; the plug the release leaves in its hole is an obstacle to
        # the states after it (one more distinct state than when nothing was left there)
        "on_error: verified from 16 states the job can fail in"
    ] * 3
    code, out = main_json("dry-run", *cam)
    assert (code, out["result_code"]) == (0, 0), (out["result_text"], out["steps"])
    assert out["parts_end_m"]["plug"][:2] == pytest.approx([0.54, 0.25], abs=0.002)


@pytest.mark.parametrize(
    "fault, code, text",
    [
        ("grip_miss@grip", 1, "grip_closed not true within 1.5 s (jaws closed on nothing)"),
        ("part_slip@approach#2", 2, "part lost in transit: the jaw sensor dropped"),
        ("estop@insert", 101, "e-stop during step 8 insert 'hole'"),
    ],
)
def test_camera_cell_faults_give_the_spec_codes(cam, fault, code, text):
    _, out = main_json("dry-run", *cam, "--inject", fault)
    assert out["result_code"] == code
    assert out["result_text"] == (text if code >= 100 else f"{text}; on_error done")


def test_a_release_whose_sensor_never_sees_the_part_is_place_failed(tmp_path):
    task = CAM_TASK.replace("release: {confirm: seated}", "release: {confirm: part_present}")
    _, out = main_json("dry-run", *project(tmp_path, CAM_CELL, task))
    assert (out["result_code"], out["result_text"]) == (
        3,
        "place failed: part_present not true within 1.5 s after the release; on_error done",
    )
