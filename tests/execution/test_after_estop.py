"""The job after an e-stop in the middle of a pick, on the twin: the arm stands with the
open fingers around the part; the next job leaves along the tool before it moves on
(cellrunner.planning.egress). Swinging home from there pushed the demo's block 54 mm off
its infeed, and the next pick then landed a pad on it (100); the kitting cell's approach
hit its bushing."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from cellrunner.sim.from_cell import description_of
from tests.conftest import ROOT
from tests.execution.twin_cell import twin_cell


def _after_estop_in_grip(cell_name: str, grip_step: int, task: int, params: dict):
    """E-stop 60 ms into the grip of a first job, released, Clear, Reset; then the job
    ``task``. Returns (first job's result, second job's result, where the cell's first
    part rests before the second job, and after it)."""
    cell = load_cell(ROOT / "cells" / f"{cell_name}.yaml")
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    backend = SimBackend(description_of(cell))
    controller, loop = twin_cell(cell, tasks, backend)
    assert controller.start_job(1, {}, "first", "cli").accepted
    for _ in range(20_000):
        loop.step()
        if controller.status().step_index == grip_step:
            break
    loop.step(30)
    backend.inject_fault("estop")
    loop.run_job(max_s=60)
    first = controller.status().last_result
    backend.release_estop()
    loop.step(3)
    assert controller.command("clear")
    loop.step(50)
    assert controller.command("reset")
    loop.step(50)
    assert controller.status().state == S.IDLE
    part = cell.cell.parts[0].name
    world = backend.world
    before = world.part_pose_world(part)[:3, 3].copy()
    assert controller.start_job(task, params, "second", "cli").accepted
    loop.run_job(max_s=120)
    after = world.part_pose_world(part)[:3, 3].copy()
    second = controller.status().last_result
    controller.close()
    return first, second, before, after


@pytest.mark.parametrize(
    ("cell", "grip_step", "params"),
    [("demo_ur5e", 4, {"slot": 1}), ("kitting_ur3e", 5, {})],
)
def test_the_next_pick_leaves_the_part_first_and_succeeds(cell, grip_step, params):
    first, second, before, after = _after_estop_in_grip(cell, grip_step, 1, params)
    assert first.result_code == ResultCode.ESTOP
    assert second.result_code == ResultCode.OK, second.result_text
    assert np.linalg.norm(after - before) > 0.1  # the part that stood in the jaws was placed


def test_going_home_leaves_the_part_where_it_rests():
    first, second, before, after = _after_estop_in_grip("demo_ur5e", 4, 2, {})
    assert first.result_code == ResultCode.ESTOP
    assert second.result_code == ResultCode.OK, second.result_text
    assert np.linalg.norm(after - before) < 0.002, after - before
