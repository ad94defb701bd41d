"""check and the run time judge the motions after an align alike (issue 33): the run
time plans a corrected pick again from where the correction left the arm, and must
choose its approach's IK branch with the corrected descend after it, as check chose
it for the corrections it proved (generated cells that check approved and the twin
ended 103 after the align corrected the pick: the files as the generator wrote them
then, tests/data/align_corrections/); and check plans the correcting line at the look
for each correction it proves as the run time plans it, and refuses it where the run
time would."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cellrunner.errors import InfeasibleError
from cellrunner.model.geometry import pose_matrix
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.align_correction import correcting_move
from cellrunner.planning.align_proof import prove_correcting_line
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.step_planner import StepPlanner
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT

DATA = ROOT / "tests" / "data" / "align_corrections"


def _world_and_task(seed):
    cell = load_cell(DATA / f"s{seed}" / "cell.yaml")
    return CellWorld(cell), load_task(DATA / f"s{seed}" / "task.yaml", cell)


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
    q = plan.replan(correcting_move(align, W @ plan.tcp_pose(q)), q, carrying=False)
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
def test_a_corrected_pick_plans_at_run_time_on_the_branch_check_proved(seed, offset):
    world, task = _world_and_task(seed)
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


def test_check_refuses_the_correcting_line_where_the_run_time_does():
    """s60130's look stands 6 deg off the wrist singularity: the straight line the run
    time makes at the look for a correction 30 mm up and aside passes under the
    planner's 3 deg; check, planning that line for the same correction, refuses it
    naming the correction, the line and the margin, and approves where the run time
    moves."""
    world, task = _world_and_task(60130)
    job = plan_job(world, task, {}, world.q_home_rad, use_cache=False)
    plan, steps = job.task_plan, {s.index: s for s in job.steps}
    align = next(s for s in job.steps if s.kind == "align")
    q_look = plan.row(steps[align.index - 1]).q_end_rad
    F = align.extra["T_world_frame"]
    verdicts = {}
    for name, C in (
        ("up and aside", pose_matrix((0.03, 0.0, 0.03), (0, 0, 0))),
        ("in the plane", pose_matrix((0.01, -0.01, 0.0), (0, 0, 5))),
    ):
        T_goal = F @ C @ np.linalg.inv(F) @ plan.tcp_pose(q_look)
        try:
            plan.replan(correcting_move(align, T_goal), q_look, carrying=False)
            run_time = None
        except InfeasibleError as exc:
            run_time = str(exc)
        checked = dataclasses.replace(align, extra={**align.extra, "correction": C})
        try:
            prove_correcting_line(StepPlanner(world, q_look, None), checked)
            check = None
        except InfeasibleError as exc:
            check = str(exc)
        verdicts[name] = (run_time, check)
    run_time, check = verdicts["up and aside"]
    assert run_time is not None and "wrist singularity" in run_time
    assert check is not None
    assert "the correcting line at the look for correction x +30.0 mm, z +30.0 mm" in check
    assert "needs >= 3.0 deg" in check
    assert verdicts["in the plane"] == (None, None)


def test_an_align_jobs_witness_keeps_its_margins_for_every_correction_check_proves():
    """The generator's aligned truth: the twin's offsets lie inside max_correction, and
    the witness (the corrected lines down and the correcting lines at the look) keeps
    its margins at the centre and every corner of it; seed 60019's first draw (a UR10
    whose look stood near the wrist singularity) is not an aligned job any more."""
    from bench.cellgen import APPROACH_M, WITNESS_MARGIN_M, generate
    from bench.cellgen_cameras import OFF_DEG, OFF_M, align_witness_clear

    for seed in (60019, 60130):
        case = generate(seed, "aligned")
        align = next(s["align"] for s in case.task["steps"] if "align" in s)
        box = align["max_correction"]
        offset = case.cell["parts"][0]["offset"]
        assert all(abs(v) <= m for v, m in zip(offset["xyz"], box["xyz"], strict=True))
        assert abs(offset["rpy"][2]) <= box["rpy"][2]
        assert box["xyz"][0] >= OFF_M and box["rpy"][2] >= OFF_DEG
        q_pick = np.radians(case.witness_deg["pick"])
        assert align_witness_clear(case, q_pick, APPROACH_M, WITNESS_MARGIN_M)


def test_the_look_takes_a_branch_from_which_every_correcting_line_clears(tmp_path):
    """A refusal that another IK branch clears is not a refusal: with a box 30 mm in x, y
    and z, s60130's nearest look branch (6 deg off the wrist singularity) cannot make
    the correcting lines up and aside, a branch on the other shoulder side (32 deg off)
    makes them all; the look takes it, and the run time streams that look."""
    task_file = tmp_path / "task.yaml"
    task_file.write_text(
        (DATA / "s60130" / "task.yaml")
        .read_text()
        .replace("xyz: [0.01, 0.01, 0]", "xyz: [0.03, 0.03, 0.03]")
        .replace("tolerance: {xyz: 0.001, rpy: 0.5}", "tolerance: {xyz: 0.01, rpy: 16}")
    )
    cell = load_cell(DATA / "s60130" / "cell.yaml")
    world, task = CellWorld(cell), load_task(task_file, cell)
    job = plan_job(world, task, {}, world.q_home_rad, use_cache=False)
    steps = {s.index: s for s in job.steps}
    align = next(s for s in job.steps if s.kind == "align")
    q_look = job.task_plan.row(steps[align.index - 1]).q_end_rad
    branches = world.kinematics.ik_all(steps[align.index - 1].T_world_tcp, world.q_home_rad)
    nearest = next(q for q in branches if world.collision.is_valid(q))
    assert world.kinematics.singularity_distance(nearest).wrist_deg < 7.0
    assert world.kinematics.singularity_distance(q_look).wrist_deg > 20.0
    for corner in ((0.03, 0.03, 0.03), (-0.03, 0.03, 0.03), (0.03, 0.0, 0.03)):
        C = pose_matrix(corner, (0, 0, 5))
        checked = dataclasses.replace(align, extra={**align.extra, "correction": C})
        prove_correcting_line(StepPlanner(world, q_look, None), checked)  # raises if refused
