"""A part a place let go stays where it was let go: an obstacle to every later step, the
support of a later place onto it (issue 33: a ceiling cell's move home swept the open
jaws through the part just set down, 126 N in the twin). A plan read back from the plan
store keeps those parts with its rows."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from cellrunner.cli.common import load
from cellrunner.model.body import Body, BodyKind
from cellrunner.model.geometry import Placed
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld
from tests.conftest import DEMO_CELL, ROOT
from tests.rig import json_of

PICK_PLACE = "  - pick: {at: infeed}\n  - place: {at: pallet, offset: [0, 0, DZ]}\n  - move: home\n"


def _task(tmp_path, places: int, dz: str = "-0.001"):
    task = tmp_path / "t.yaml"
    task.write_text("task: t\nsteps:\n  - move: home\n" + PICK_PLACE.replace("DZ", dz) * places)
    return task


def test_placing_twice_at_one_frame_meets_the_first_part(tmp_path) -> None:
    """The second block is set down where the first one lies: refused, naming it."""
    out = json_of("check", str(DEMO_CELL), str(_task(tmp_path, 2)), "--no-cache")
    assert not out["ok"]
    assert out["errors"][0].startswith(
        "step 16 descend 'pallet': at its end the part 'block' would be 50.0 mm inside "
        "placed part 'block@8'"
    ), out["errors"]


def test_a_part_set_down_is_an_obstacle_to_the_steps_after_it(tmp_path) -> None:
    """After the release, the rows plan in a world with the block where it was let go,
    and the move home keeps the cell's clearance from it."""
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(DEMO_CELL), str(_task(tmp_path, 1)))
    world = CellWorld(cell)
    plan = plan_job(world, task, {}, world.q_home_rad, use_cache=False)
    assert plan.ok, plan.errors
    release = next(r for r in plan.rows if r.step.kind == "release")
    for row in plan.task_plan.rows:
        placed = row.world.placed if row.world is not None else ()
        assert bool(placed) == (row.step.index >= release.step.index), row.step.label
    home = plan.task_plan.rows[-1]
    assert home.step.kind == "move" and home.world is not None
    (block,) = home.world.placed
    assert Body.fixture(block.name) == Body(BodyKind.PLACED_PART, "block@8")
    # the block lies on the pallet table where the jaws let it go (its centre ~25 mm up)
    descend = next(r for r in plan.rows if r.step.index == release.step.index - 1)
    assert descend.step.kind == "descend" and descend.q_end_rad is not None
    T_tcp = world.kinematics.T_world_tcp(descend.q_end_rad)
    assert np.allclose(block.T_parent_shape[:3, 3], T_tcp[:3, 3], atol=0.03)
    approved = plan.motions.nominal(home.step)
    assert approved is not None
    model = home.world.collision
    q = approved.trajectory.q_rad
    for k in range(0, len(q), 5):
        clearance = model.clearance(q[k])
        assert clearance.distance_m >= clearance.required_m - 1e-4, (k, clearance)


def test_a_stored_plan_keeps_the_parts_set_down(tmp_path) -> None:
    """Read back from the plan store, the rows after the release plan in the world with
    the block, the very world planning used (shared, with its collision model)."""
    cell_file = tmp_path / "cell.yaml"
    cell_file.write_text(DEMO_CELL.read_text())
    for mesh in DEMO_CELL.parent.iterdir():
        if mesh.suffix.lower() == ".stl":
            (tmp_path / mesh.name).write_bytes(mesh.read_bytes())
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(cell_file), str(_task(tmp_path, 1)))
    planned = CellWorld(cell)
    first = plan_job(planned, task, {}, planned.q_home_rad)
    assert first.ok, first.errors
    assert planned.plans.has(first.key)
    fresh = CellWorld(cell)  # a new process: the plan comes from the file
    again = plan_job(fresh, task, {}, fresh.q_home_rad)
    assert again.key == first.key
    for a, b in zip(first.task_plan.rows, again.task_plan.rows, strict=True):
        assert a.world is not None and b.world is not None
        assert [p.name for p in a.world.placed] == [p.name for p in b.world.placed]
        for p, r in zip(a.world.placed, b.world.placed, strict=True):
            assert np.allclose(p.T_parent_shape, r.T_parent_shape)
    home = again.task_plan.rows[-1]
    assert home.world is not None and home.world.placed
    assert home.world is fresh.with_placed(*home.world.placed)
    assert home.approved is None  # read from the file, not planned: sealed on first use
    assert again.motions.nominal(home.step) is not None  # verified again, block and all


def test_a_world_with_placed_parts_shares_the_arm_and_mounts_tools_with_them(tmp_path) -> None:
    with contextlib.redirect_stderr(io.StringIO()):
        cell, _ = load(str(DEMO_CELL), str(_task(tmp_path, 1)))
    world = CellWorld(cell)
    kinematics = world.kinematics
    part = world.waiting_parts[0]
    placed = world.with_placed(Placed("placed:block@3", part.shape, part.T_parent_shape))
    assert placed.kinematics is kinematics and placed.plans is world.plans
    assert placed.with_placed() is placed
    assert world.with_placed(*placed.placed) is placed
    assert [p.name for p in placed.waiting_parts][-1] == "placed:block@3"


def test_a_tool_change_keeps_the_parts_set_down() -> None:
    with contextlib.redirect_stderr(io.StringIO()):
        cell, _ = load(str(ROOT / "cells/cnc_tending_ur5e.yaml"), str(ROOT / "tasks/cnc_tend.yaml"))
    world = CellWorld(cell)
    part = world.waiting_parts[0]
    placed = world.with_placed(Placed("placed:raw@3", part.shape, part.T_parent_shape))
    other = placed.with_tool("finished")
    assert other.loaded.cell.tool == cell.cell.tools["finished"]
    assert other.placed == placed.placed and other.kinematics is not world.kinematics
    assert other.with_tool("raw") is placed


def test_a_placed_part_is_named_in_failures() -> None:
    body = Body.fixture("placed:carton@12")
    assert (body.kind, body.name, body.is_obstacle, str(body)) == (
        BodyKind.PLACED_PART,
        "carton@12",
        True,
        "placed part 'carton@12'",
    )
    assert body.fixture_name == "placed:carton@12"


def test_one_place_and_the_move_home_check_feasible(tmp_path) -> None:
    out = json_of("check", str(DEMO_CELL), str(_task(tmp_path, 1)), "--no-cache")
    assert out["ok"], out["errors"]


PALLET_CELL = ROOT / "cells/palletizer_ur10e.yaml"


def _palletize(tmp_path, pitch: str):
    text = (ROOT / "tasks/palletize.yaml").read_text()
    task = tmp_path / "palletize.yaml"
    task.write_text(text.replace("pitch: [0.22, 0.17, 0.10]", f"pitch: {pitch}"))
    assert task.read_text() != text
    return task


def test_a_layer_pitch_under_the_carton_is_refused_on_the_carton_below(tmp_path) -> None:
    """Cartons 100 mm tall stacked 90 mm apart: slot 4 comes down 10 mm into slot 0's
    carton, which an earlier job put there (the twin spawns it too)."""
    task = _palletize(tmp_path, "[0.22, 0.17, 0.09]")
    out = json_of("check", str(PALLET_CELL), str(task), "-p", "slot=4", "--no-cache")
    assert not out["ok"]
    assert any(
        "the part 'carton' would be 10.0 mm inside placed part 'carton@slot0'" in e
        for e in out["errors"]
    ), out["errors"]


def test_a_column_pitch_equal_to_the_carton_is_refused_beside_the_carton_before(
    tmp_path,
) -> None:
    """Cartons 150 mm wide laid 150 mm apart: slot 1 comes down touching slot 0's
    carton, inside the cell's clearance of it."""
    task = _palletize(tmp_path, "[0.22, 0.15, 0.10]")
    out = json_of("check", str(PALLET_CELL), str(task), "-p", "slot=1", "--no-cache")
    assert not out["ok"]
    assert any(
        "the part 'carton' would be 0.0 mm from placed part 'carton@slot0' beside it" in e
        for e in out["errors"]
    ), out["errors"]


def test_the_earlier_slots_are_there_from_the_start_of_the_job() -> None:
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(PALLET_CELL), str(ROOT / "tasks/palletize.yaml"))
    world = CellWorld(cell)
    plan = plan_job(world, task, {"slot": 5}, world.q_home_rad, use_cache=False)
    assert plan.ok, plan.errors
    first = plan.task_plan.rows[0].world
    assert first is not None
    names = [p.name for p in first.placed]
    assert names == [f"placed:carton@slot{k}" for k in range(5)]
    # slot 4's carton lies on slot 0's, 100 mm up
    (slot0,) = (p for p in first.placed if p.name.endswith("@slot0"))
    (slot4,) = (p for p in first.placed if p.name.endswith("@slot4"))
    assert np.allclose(slot4.T_parent_shape[:3, 3] - slot0.T_parent_shape[:3, 3], [0, 0, 0.1])


def test_the_demo_pattern_checks_feasible_with_its_earlier_blocks(tmp_path) -> None:
    """The demo's 70 mm pitch around 50 mm blocks: the jaws, closed on the block they
    carry, pass the blocks beside its slot (check models the pads fully open)."""
    out = json_of(
        "check", str(DEMO_CELL), str(ROOT / "tasks/pick_place.yaml"), "-p", "slot=10", "--no-cache"
    )
    assert out["ok"], out["errors"]


def test_a_part_an_align_finds_off_its_frame_lies_within_its_max_correction() -> None:
    """A part off its frame (``offset``) is no waiting part (a camera finds it), but the
    align's max_correction bounds where it lies: an obstacle grown by that box, named as
    a waiting part, until the job carries it (s90344)."""
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.placed import found_parts

    folder = ROOT / "tests" / "data" / "generated" / "s90344-ur16e-aligned"
    cell = load_cell(folder / "cell.yaml")
    task = load_task(folder / "task.yaml", cell)
    world = CellWorld(cell)
    assert [p.name for p in world.waiting_parts] == []  # off its frame: where? (a camera)
    (found,) = found_parts(world, list(task.steps))
    assert Body.fixture(found.name) == Body(BodyKind.WAITING_PART, "part")
    (part,) = cell.cell.parts
    size = np.asarray(part.box.size)
    align = next(s for s in task.steps if s.kind == "align")
    dx, dy, _ = align.args.max_correction.xyz
    turn = np.sin(np.radians(align.args.max_correction.rpy[2]))
    grown = np.asarray(found.shape.size_m)
    assert grown[0] == pytest.approx(size[0] + 2 * dx + size[1] * turn)
    assert grown[1] == pytest.approx(size[1] + 2 * dy + size[0] * turn)
    assert grown[2] == pytest.approx(size[2])
    # where it lies: the frame, the box centred on it (the jaws grip the part's centre)
    frame = np.asarray(cell.cell.frames["infeed"].xyz)
    assert np.allclose(found.T_parent_shape[:3, 3], frame, atol=1e-9)
    # the part as the twin puts it (its offset) lies inside the grown box
    offset = np.asarray(part.offset.xyz)
    assert np.all(np.abs(offset[:2]) + size[:2] / 2 <= grown[:2] / 2)
    # a job without the align does not know it
    no_align = [s for s in task.steps if s.kind != "align"]
    assert found_parts(world, no_align) == ()
