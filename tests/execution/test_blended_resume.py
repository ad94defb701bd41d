"""A blended motion interrupted by a protective stop: the step it blends into was planned
to start moving, so after the resume (which ends at rest) it is replanned from rest."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from cellrunner.cli.common import load
from cellrunner.execution.context import JobContext
from cellrunner.execution.job import JobRunner
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import expand, resolve_params
from cellrunner.planning.task_plan import plan_task
from cellrunner.planning.timing import sample_measures
from cellrunner.planning.world import CellWorld
from tests.conftest import DEMO_CELL, PICK_PLACE
from tests.execution.fakes import ScriptedArm


class RecordingArm(ScriptedArm):
    """The scripted arm, keeping every set-point it was sent with its step."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.sent: list[tuple[int, np.ndarray]] = []

    def servo(self, approved, index):
        super().servo(approved, index)
        self.sent.append((approved.step_index, approved.trajectory.q_rad[index].copy()))


def test_a_stop_in_a_blended_approach_replans_the_descend_from_rest():
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(DEMO_CELL), str(PICK_PLACE))
    world = CellWorld(cell)
    steps = expand(task, cell.cell, resolve_params(task.task, {}))
    plan = plan_task(world, steps, world.q_home_rad)
    approach, descend = (
        # the pick's: a place's descend starts from rest (docs/check-truth.md, set-down)
        next(s for s in steps if s.kind == k and s.name == "infeed")
        for k in ("approach", "descend")
    )
    assert plan.continues(descend) and not plan.continues(approach)
    arm = RecordingArm(q=world.q_home_rad.copy())
    ctx = JobContext(
        backend=arm,
        motions=plan,
        outputs={"gripper_close": "DO0", "beacon": "DO3"},
        inputs={"gripper_closed": "DI0", "part_present": "DI1"},
        gripper_close=("DO0", True),
        gripper_open=None,
        gripper_closed_sensor="DI0",
    )
    runner = JobRunner(ctx, steps, task.task.on_protective_stop)
    runner.start()
    for _ in range(200_000):
        if runner.done:
            break
        if (
            arm.protective_stop_at_s is None
            and runner.protective_stops == 0
            and arm.sent
            and arm.sent[-1][0] == approach.index
        ):
            arm.protective_stop_at_s = arm.t + 0.5  # half a second into the infeed approach
        arm.wait_period()
        runner.tick()
    assert runner.result is ResultCode.OK, runner.message
    assert runner.protective_stops == 1
    streamed = np.array([q for index, q in arm.sent if index == descend.index])
    nominal = plan.nominal(descend).trajectory.q_rad
    assert not np.allclose(
        streamed[: len(nominal)][:5], nominal[1:6]
    )  # not the planned, moving start
    # from rest: every joint within its acceleration limit from the first set-point on
    before = np.array([q for index, q in arm.sent if index == approach.index])[-1]
    _, accel, _ = sample_measures(
        world.kinematics, np.vstack([before, streamed]), world.spec.rate_hz
    )
    assert (np.abs(accel) <= world.limits.joint_accel_rad_s2 * (1 + 1e-6)).all()
