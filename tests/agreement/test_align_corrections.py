"""check and the run time judge the motions after an align alike (issue 33): the run
time plans a corrected pick again from where the correction left the arm, and must
choose its approach's IK branch with the corrected descend after it, as check chose
it for the corrections it proved; generated cells that check approved and the twin
ended 103 after the align corrected the pick."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.cellgen import generate
from cellrunner.errors import InfeasibleError
from cellrunner.execution.align import _correcting_move
from cellrunner.model.geometry import pose_matrix
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld


def _world_and_task(tmp_path, seed):
    cell_file, task_file = generate(seed, "aligned").write(tmp_path / f"s{seed}")
    cell = load_cell(cell_file)
    return CellWorld(cell), load_task(task_file, cell)


def _as_run(world, task, C):
    """The run time after an align measured ``C`` (in the frame's axes): the look, the
    correcting line, then the corrected approach and descend each planned again from
    where the arm stands (what :func:`cellrunner.execution.steps.run_motion` does); the
    arm's configuration at the end of each."""
    job = plan_job(world, task, {}, world.q_home_rad, use_cache=False)
    assert job.ok, job.failures
    plan, steps = job.task_plan, {s.index: s for s in job.steps}
    align = next(s for s in job.steps if s.kind == "align")
    q = plan.row(steps[align.index - 1]).q_end_rad  # the look
    F = align.extra["T_world_frame"]
    W = F @ C @ np.linalg.inv(F)
    q = plan.replan(_correcting_move(align, W @ plan.tcp_pose(q)), q, carrying=False)
    q = q.trajectory.q_rad[-1]
    ends = {}
    for step in (steps[align.index + 1], steps[align.index + 2]):  # approach, descend
        moved = dataclasses.replace(
            step, T_world_tcp=W @ step.T_world_tcp, extra={**step.extra, "corrects": step}
        )
        q = plan.replan(moved, q, carrying=False).trajectory.q_rad[-1]
        ends[step.kind] = q
    return ends


@pytest.mark.parametrize(
    ("seed", "offset"),
    [
        # UR10 on a 1.4 m pedestal: the approach's nearest branch from the corrected
        # look descends through the wrist singularity (wrist 2 at 0.7 deg)
        (60130, ((-0.002, 0.0002, 0.0), (0.0, 0.0, 3.0))),
        # UR16e: the nearest branch's forearm passes the infeed table 0.02 mm short
        (60148, ((-0.0043, 0.0007, 0.0), (0.0, 0.0, 2.52))),
    ],
)
def test_a_corrected_pick_plans_at_run_time_on_the_branch_check_proved(tmp_path, seed, offset):
    world, task = _world_and_task(tmp_path, seed)
    C = pose_matrix(*offset)
    try:
        ends = _as_run(world, task, C)
    except InfeasibleError as exc:  # what the twin ended 103 with
        pytest.fail(f"s{seed}: the corrected pick is refused at run time: {exc}")
    # the branch check proved for that correction
    proved = plan_job(
        world,
        task,
        {"align:infeed": {"xyz": list(offset[0]), "rpy": list(offset[1])}},
        world.q_home_rad,
        use_cache=False,
    )
    assert proved.ok, proved.failures
    descend = next(s for s in proved.steps if s.kind == "descend" and s.name == "infeed")
    q_proved = proved.task_plan.row(descend).q_end_rad
    # the same branch: the same signs of elbow and wrist 2, the joints within degrees
    # (the look it starts from differs by the correction)
    assert np.degrees(np.abs(ends["descend"] - q_proved))[:5].max() < 10.0
