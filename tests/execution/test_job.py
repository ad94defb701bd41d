"""The job runner, tick by tick: normal jobs, retries, slips, stops, aborts, timeouts."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.execution.context import JobContext
from cellrunner.execution.job import JobRunner
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import expand, resolve_params
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.task import ProtectiveStopPolicy
from tests.conftest import DEMO_CELL, PICK_PLACE
from tests.execution.fakes import MAX_TICKS, LineMotions, ScriptedArm, run


def make(arm: ScriptedArm, policy=None, task=PICK_PLACE, **kw):
    cell = load_cell(DEMO_CELL)
    loaded = load_task(task, cell)
    steps = expand(loaded, cell.cell, resolve_params(loaded.task, {}))
    motions = LineMotions(steps)
    ctx = JobContext(
        backend=arm,
        motions=motions,
        outputs={"gripper_close": "DO0", "beacon": "DO3"},
        inputs={"gripper_closed": "DI0", "part_present": "DI1"},
        gripper_close=("DO0", True),
        gripper_open=None,
        gripper_closed_sensor="DI0",
    )
    runner = JobRunner(ctx, steps, policy or loaded.task.on_protective_stop, **kw)
    return runner, motions


def statuses(runner):
    return [(r.index, r.kind, r.status, r.attempts) for r in runner.records.values()]


def test_normal_job_completes_ok():
    arm = ScriptedArm()
    runner, _ = make(arm)
    run(runner, arm)
    assert runner.result is ResultCode.OK, runner.message
    assert all(r.status == "ok" for r in runner.records.values())
    assert runner.retries_used == 0
    assert runner.cycle_time_s == pytest.approx(arm.t, abs=0.01)
    assert runner.records[4].attempts == 1


def test_grip_miss_retries_then_no_part():
    arm = ScriptedArm(part_present=False)
    runner, _ = make(arm)
    run(runner, arm)
    assert runner.result is ResultCode.NO_PART
    assert runner.retries_used == 2
    grip = runner.records[4]
    assert (grip.status, grip.attempts) == ("failed", 3)
    assert "gripper_closed not true within 1.5 s" in grip.message
    assert [r.status for r in runner.records.values()][4:] == ["skipped"] * 6
    assert arm.outputs["DO0"] is False  # the retry's release ran before the job ended


def test_grip_succeeds_on_second_attempt():
    arm = ScriptedArm(part_present=False)
    runner, motions = make(arm)
    runner.start()
    for _ in range(MAX_TICKS):
        if runner.retries_used == 1:
            arm.part_present = True  # somebody put the part back
        if runner.done:
            break
        arm.wait_period()
        runner.tick()
    assert runner.result is ResultCode.OK, runner.message
    assert runner.retries_used == 1
    assert runner.records[4].attempts == 2
    assert motions.replans >= 2  # retreat and the new descend start where the arm is


def test_light_part_fails_force_window():
    arm = ScriptedArm(part_mass_kg=0.05)  # 0.5 N < min 2 N
    runner, _ = make(arm)
    run(runner, arm)
    assert runner.result is ResultCode.NO_PART
    assert "load 0.5 N after lift is outside [2, 40] N" in runner.records[4].message


def test_part_slip_in_transit_is_part_lost():
    arm = ScriptedArm()
    runner, _ = make(arm)
    runner.start()
    for _ in range(MAX_TICKS):
        if runner.done:
            break
        if runner.current_step == 6 and arm.drop_part_at_s is None and arm.part_present:
            arm.drop_part_at_s = arm.t + 0.05
        arm.wait_period()
        runner.tick()
    assert runner.result is ResultCode.PART_LOST
    assert runner.records[6].status == "failed"
    assert runner.message.startswith(
        "part lost in transit: the "
    )  # jaw sensor or wrist load, whichever first


def test_protective_stop_is_held_5s_then_resumed():
    arm = ScriptedArm(protective_stop_at_s=0.1)  # during the first move
    runner, motions = make(arm)
    phases = []
    runner.start()
    for _ in range(MAX_TICKS):
        if runner.done:
            break
        arm.wait_period()
        runner.tick()
        if not phases or phases[-1][0] != runner.phase:
            phases.append((runner.phase, round(arm.t, 3)))
    assert runner.result is ResultCode.OK, runner.message
    names = [p for p, _ in phases]
    assert names[0] == "execute" and "held" in names
    held_at = phases[1][1]  # the first tick after the stop: holding, or held at once
    resumed_at = next(t for p, t in phases[2:] if p == "execute")
    assert 5.0 <= resumed_at - held_at < 5.1
    assert runner.protective_stops == 1
    assert motions.replans >= 1  # the interrupted move continued from where the arm stood


def test_protective_stop_without_resume_ends_100():
    arm = ScriptedArm(protective_stop_at_s=0.1)
    runner, _ = make(arm, policy=ProtectiveStopPolicy(resume=False))
    run(runner, arm)
    assert runner.result is ResultCode.PROTECTIVE_STOP
    assert "does not resume" in runner.message


def test_estop_aborts_101():
    arm = ScriptedArm(estop_at_s=0.3)
    runner, _ = make(arm)
    run(runner, arm)
    assert runner.result is ResultCode.ESTOP
    assert runner.records[1].status == "failed" or runner.records[2].status == "failed"


def test_disconnect_is_102():
    arm = ScriptedArm(disconnect_at_s=0.3)
    runner, _ = make(arm)
    run(runner, arm)
    assert runner.result is ResultCode.ROBOT_CONNECTION_LOST


def test_hold_unhold_and_abort_requests():
    arm = ScriptedArm()
    runner, _ = make(arm, wait_for_unhold=True)
    runner.start()
    for _ in range(100):
        arm.wait_period()
        runner.tick()
    runner.request("hold")
    for _ in range(50):
        arm.wait_period()
        runner.tick()
    assert runner.phase == "held"
    servos = arm.servo_count
    for _ in range(500):
        arm.wait_period()
        runner.tick()
    assert arm.servo_count == servos  # nothing moves while held
    runner.request("unhold")
    arm.wait_period()
    runner.tick()
    assert runner.phase == "execute"
    runner.request("abort")
    arm.wait_period()
    runner.tick()
    assert runner.result is ResultCode.ABORTED_BY_PLC


def test_wait_input_timeout_is_105(tmp_path):
    task = tmp_path / "t.yaml"
    task.write_text(
        "task: t\nsteps:\n  - wait_input: {input: part_present, value: true, timeout: 0.5}\n"
    )
    arm = ScriptedArm()
    runner, _ = make(arm, task=task)
    run(runner, arm)
    assert runner.result is ResultCode.STEP_TIMEOUT
    assert runner.cycle_time_s == pytest.approx(0.5, abs=0.01)


def test_carried_load_takes_the_tool_and_part_inertia_out_of_the_wrist_reading():
    """A reading as the twin makes it (external force, base axes, tool weight compensated):
    m_part (g - a) - m_tool a. Held, the part weighs m_part g whatever the acceleration;
    lost, ~0; without the planned acceleration the old reading (which fell to 4.9 N for a
    2 kg carton on a 2.5 kg tool at 5 m/s^2)."""
    from cellrunner.execution.context import Carry
    from cellrunner.execution.steps import carried_load_N

    g = np.array([0.0, 0.0, -9.81])
    carry = Carry(baseline_N=np.array([0.3, -0.2, 0.1]), tool_mass_kg=2.5)
    rng = np.random.default_rng(3)
    for a in [np.zeros(3), np.array([0.0, 0.0, -5.0]), *rng.uniform(-6, 6, (20, 3))]:
        held = carry.baseline_N + 2.0 * (g - a) - 2.5 * a
        lost = carry.baseline_N - 2.5 * a
        assert carried_load_N(held.tolist(), carry, a, g) == pytest.approx(2.0 * 9.81)
        assert carried_load_N(lost.tolist(), carry, a, g) == pytest.approx(0.0, abs=1e-9)
    a = np.array([0.0, 0.0, 5.0])  # upward: the reading alone sees the weight grow
    held = carry.baseline_N + 2.0 * (g - a) - 2.5 * a
    assert carried_load_N(held.tolist(), carry) == pytest.approx(
        float(np.linalg.norm(held - carry.baseline_N))
    )
