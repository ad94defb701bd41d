"""A motion that ends at rest ends where the arm stands at its last set-point: the stream
of a loaded sender can leave the servo behind when it ends (a job through ur_rtde once
ended OK with the arm 5 deg short of home). Here the twin loses the last 60 set-points of
each move as they are first sent: the step holds its last set-point until the arm is
there; an arm that never gets there fails the step (105), never OK."""

from __future__ import annotations

import time

import numpy as np

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from cellrunner.sim.from_cell import description_of
from tests.conftest import DEMO_CELL
from tests.execution.twin_cell import twin_cell

TASK = """task: out_and_home
steps:
  - move: [30, -90, 90, -90, -90, 0]
  - move: home
"""


class LossySide(SimBackend):
    """Set-points near the end of a trajectory are lost the first time they are sent
    (all of them, with ``stuck``)."""

    LOST = 60

    def __init__(self, *args, stuck: bool = False, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.stuck, self.sent = stuck, set()

    def servo(self, trajectory, index: int) -> None:
        first = (id(trajectory), index) not in self.sent
        self.sent.add((id(trajectory), index))
        if index >= len(trajectory.trajectory.q_rad) - self.LOST and (first or self.stuck):
            return  # lost on the way
        super().servo(trajectory, index)


def _run(tmp_path, stuck: bool):
    cell = load_cell(DEMO_CELL)
    (tmp_path / "t.yaml").write_text(TASK)
    backend = LossySide(description_of(cell), stuck=stuck)
    controller, loop = twin_cell(cell, {1: load_task(tmp_path / "t.yaml", cell)}, backend)
    assert controller.start_job(1, {}, "arrive", "cli").accepted
    # planning runs on a worker thread while the loop steps: bounded in time, not in a
    # count of steps that a loaded machine's planning can outlast
    deadline = time.monotonic() + 120.0
    for _ in range(10_000_000):
        loop.step()
        if controller.status().last_result is not None or time.monotonic() > deadline:
            break
    result = controller.status().last_result
    q = backend.read_state().q_rad
    controller.close()
    return result, q, np.radians(cell.cell.robot.home)


def test_a_job_ends_with_the_arm_at_home_not_short_of_it(tmp_path):
    result, q, home = _run(tmp_path, stuck=False)
    assert result.result_code == ResultCode.OK, result.result_text
    assert np.degrees(np.abs(q - home)).max() < 1.0


def test_an_arm_that_never_arrives_fails_the_step(tmp_path):
    result, _, _ = _run(tmp_path, stuck=True)
    assert result.result_code == ResultCode.STEP_TIMEOUT, result.result_text
    assert result.result_text.startswith("the arm stopped ")
    assert "deg short of the end of step 2 move on joint 1" in result.result_text
