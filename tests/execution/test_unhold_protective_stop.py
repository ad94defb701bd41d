"""A PLC's Unhold while a protective stop holds the job (serve: the cell waits for the
PLC's Unhold when the task does not resume by itself). The controller is still stopped:
Unhold means unlock it once its delay has passed, then resume. Resuming at once would
only meet the stop again, count it as another one and, pressed every 0.5 s as the soak's
PLC does, end a recoverable job with 100 (or leave it held for good). On the demo cell
and the MuJoCo twin, through the real cell controller."""

from __future__ import annotations

import pytest

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.model.codes import PackMLState as S
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from cellrunner.sim.from_cell import description_of
from tests.conftest import ROOT
from tests.execution.twin_cell import twin_cell

#: the controller refuses to unlock a stop sooner (job.UNLOCK_DELAY_S)
UNLOCK_DELAY_S = 5.0


def _held_job(tmp_path, resume: bool, press_every_s: float | None):
    """The demo's pick and place, a protective stop during its approach, Unhold pressed
    every ``press_every_s`` while the cell is Held (None: never). Returns the result,
    the protective stops counted and the simulated seconds from the stop to Execute."""
    cell = load_cell(ROOT / "cells" / "demo_ur5e.yaml")
    text = (ROOT / "tasks" / "pick_place.yaml").read_text()
    policy = "on_protective_stop: {resume: true, max: 2}"
    assert policy in text
    if not resume:
        text = text.replace(policy, "on_protective_stop: {resume: false}")
    path = tmp_path / "pick_place.yaml"
    path.write_text(text)
    backend = SimBackend(description_of(cell))
    controller, loop = twin_cell(cell, {1: load_task(path, cell)}, backend, wait_for_unhold=True)
    assert controller.start_job(1, {"slot": 0}, "held", "plc").accepted
    stopped_at = pressed_at = resumed_at = None
    for _ in range(100_000):
        loop.step()
        status = controller.status()
        now = backend.read_state().time_s
        if stopped_at is None and status.step_index == 2 and status.state == S.EXECUTE:
            loop.step(100)  # into the approach
            backend.inject_fault("protective_stop")
            stopped_at = backend.read_state().time_s
        elif stopped_at is not None and resumed_at is None and status.state == S.EXECUTE:
            resumed_at = now
        if (
            status.state == S.HELD
            and press_every_s is not None
            and (pressed_at is None or now - pressed_at >= press_every_s)
        ):
            controller.command("unhold")
            pressed_at = now
        if status.last_result is not None or (
            press_every_s is None and not resume and now - (stopped_at or now) > 30.0
        ):
            break
    result = controller.status().last_result
    stops = controller.last_runner.protective_stops if controller.last_runner else 0
    state = controller.status().state
    controller.close()
    return result, stops, state, None if resumed_at is None else resumed_at - stopped_at


@pytest.mark.parametrize("resume", [True, False])
def test_unhold_pressed_during_a_protective_stop_unlocks_then_resumes(tmp_path, resume):
    result, stops, _, resumed_after_s = _held_job(tmp_path, resume, press_every_s=0.5)
    assert result is not None and result.result_code == ResultCode.OK, result
    assert stops == 1  # the presses are not stops
    assert UNLOCK_DELAY_S <= resumed_after_s < UNLOCK_DELAY_S + 0.5


def test_without_unhold_a_job_that_does_not_resume_stays_held(tmp_path):
    result, _, state, resumed_after_s = _held_job(tmp_path, False, press_every_s=None)
    assert result is None and state == S.HELD and resumed_after_s is None  # 30 s on
