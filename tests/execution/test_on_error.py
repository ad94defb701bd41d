"""Tick by tick: a task's on_error steps after a failed job, journaled with it; pulses;
a place confirmed by its input (SPEC section 11)."""

from __future__ import annotations

import pytest

from cellrunner.execution.context import JobContext
from cellrunner.execution.job import JobRunner
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import expand, expand_on_error, resolve_params
from cellrunner.model.load import load_cell, load_task
from tests.conftest import DEMO_CELL
from tests.execution.fakes import LineMotions, ScriptedArm, run


def make(arm: ScriptedArm, tmp_path, text: str, journal: list):
    cell = load_cell(DEMO_CELL)
    path = tmp_path / "t.yaml"
    path.write_text(text)
    loaded = load_task(path, cell)
    params = resolve_params(loaded.task, {})
    steps = expand(loaded, cell.cell, params)
    steps += expand_on_error(loaded, cell.cell, params, len(steps) + 1)
    ctx = JobContext(
        backend=arm,
        motions=LineMotions(steps),
        outputs={"gripper_close": "DO0", "beacon": "DO3"},
        inputs={"gripper_closed": "DI0", "part_present": "DI1"},
        gripper_close=("DO0", True),
        gripper_open=None,
        gripper_closed_sensor="DI0",
    )
    return JobRunner(
        ctx,
        steps,
        loaded.task.on_protective_stop,
        on_step=lambda record, attempt: journal.append((record.index, record.kind, record.status)),
    )


FAILING = """task: t
steps:
  - set_output: {beacon: true}
  - wait_input: {input: part_present, value: true, timeout: 0.3}
  - wait: 1
on_error:
  - set_output: {beacon: false}
  - wait: "100 ms"
"""


def test_on_error_runs_after_a_failure_and_is_journaled_with_the_job(tmp_path):
    arm, journal = ScriptedArm(), []
    runner = make(arm, tmp_path, FAILING, journal)
    run(runner, arm)
    assert runner.result is ResultCode.STEP_TIMEOUT
    assert runner.message == "input part_present did not read True within 0.3 s; on_error done"
    assert arm.outputs["DO3"] is False
    assert [(r.index, r.status) for r in runner.records.values()] == [
        (1, "ok"),
        (2, "failed"),
        (3, "skipped"),
        (4, "ok"),
        (5, "ok"),
    ]
    assert (4, "set_output", "ok") in journal and (5, "wait", "ok") in journal
    assert runner.cycle_time_s == pytest.approx(0.3 + 0.1, abs=0.02)


def test_no_on_error_after_a_job_that_went_well(tmp_path):
    arm, journal = ScriptedArm(), []
    runner = make(
        arm,
        tmp_path,
        FAILING.replace(
            "  - wait_input: {input: part_present, value: true, timeout: 0.3}\n", "  - wait: 0.1\n"
        ),
        journal,
    )
    run(runner, arm)
    assert runner.result is ResultCode.OK
    assert [r.index for r in runner.records.values()] == [1, 2, 3]  # no on_error rows
    assert arm.outputs["DO3"] is True


def test_no_on_error_when_the_arm_cannot_move(tmp_path):
    arm, journal = ScriptedArm(estop_at_s=0.5), []
    runner = make(arm, tmp_path, FAILING.replace("timeout: 0.3", "timeout: 3"), journal)
    run(runner, arm)
    assert runner.result is ResultCode.ESTOP
    assert "on_error" not in runner.message
    assert all(index <= 3 for index, _, _ in journal)


def test_a_pulse_sets_the_output_back_after_its_length(tmp_path):
    arm, journal = ScriptedArm(), []
    runner = make(
        arm, tmp_path, "task: t\nsteps:\n  - set_output: {beacon: true, pulse: '250 ms'}\n", journal
    )
    seen = []
    runner.start()
    while not runner.done:
        arm.wait_period()
        runner.tick()
        seen.append((round(arm.t, 3), arm.outputs.get("DO3")))
    high = [t for t, v in seen if v is True]
    assert high[-1] - high[0] == pytest.approx(0.25, abs=0.005)
    assert arm.outputs["DO3"] is False and runner.result is ResultCode.OK


def test_a_place_whose_confirm_input_stays_false_is_place_failed(tmp_path):
    arm, journal = ScriptedArm(), []
    runner = make(
        arm,
        tmp_path,
        """task: t
steps:
  - pick: {at: infeed}
  - place: {at: pallet, confirm: part_present, release: {timeout: 0.5}}
""",
        journal,
    )
    run(runner, arm)
    assert runner.result is ResultCode.PLACE_FAILED
    assert runner.message == "place failed: part_present not true within 0.5 s after the release"
