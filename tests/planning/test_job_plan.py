"""The plan of one job as the object everything shares: steps expanded once, failures as
data (which step, why, what blocked it), stored plans found by the digests taken on
loading, on_error proofs shared between jobs whose states are the same."""

from __future__ import annotations

import contextlib
import dataclasses
import io

import pytest

import cellrunner.model.expand as expand_module
from cellrunner.cli.common import load, parse_params
from cellrunner.model.failure import FailureKind
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT


def _load(cell: str, task: str):
    with contextlib.redirect_stderr(io.StringIO()):
        return load(str(ROOT / cell), str(ROOT / task))


def test_a_job_is_expanded_once_and_its_plan_is_frozen(monkeypatch) -> None:
    cell, task = _load("cells/demo_ur5e.yaml", "tasks/pick_place.yaml")
    world = CellWorld(cell)
    calls = []
    original = expand_module.expand  # plan_job expands through model.job_steps
    monkeypatch.setattr(
        expand_module, "expand", lambda *a, **k: calls.append(1) or original(*a, **k)
    )
    seen = []
    plan = plan_job(world, task, parse_params(["slot=3"], task), world.q_home_rad,
                    use_cache=False, on_step=seen.append)  # fmt: skip
    assert plan.ok and not plan.failures
    assert len(calls) == 1
    assert [s.index for s in seen] == [s.index for s in plan.steps]
    assert plan.params == {"slot": 3}
    with pytest.raises(dataclasses.FrozenInstanceError):
        plan.speed = 0.5  # type: ignore[misc]
    slow = plan.paced(0.5)
    assert slow.planned_cycle_time_s == pytest.approx(2 * plan.cycle_time_s)
    step = next(s for s in plan.steps if s.kind == "approach")
    fast, stretched = plan.motions.nominal(step), slow.motions.nominal(step)
    assert fast is not None and stretched is not None
    assert len(stretched.trajectory.q_rad) > 1.9 * len(fast.trajectory.q_rad)


def test_a_failure_is_data_naming_its_step(tmp_path) -> None:
    """A frame out of reach: the failure carries the approach's index and a message
    without the step's name in front; the row and the error line agree with it."""
    text = (ROOT / "cells/demo_ur5e.yaml").read_text()
    cell_file = tmp_path / "cells" / "far.yaml"
    cell_file.parent.mkdir()
    far = text.replace("pallet: {xyz: [0.25, 0.20, 0.928]", "pallet: {xyz: [3.0, 3.0, 0.928]")
    assert far != text
    cell_file.write_text(far)
    with contextlib.redirect_stderr(io.StringIO()):
        cell, task = load(str(cell_file), str(ROOT / "tasks/pick_place.yaml"))
    world = CellWorld(cell)
    plan = plan_job(world, task, {"slot": 0}, world.q_home_rad, use_cache=False)
    assert not plan.ok and len(plan.failures) == 1
    failure = plan.failures[0]
    failed = next(r for r in plan.rows if r.status == "failed")
    assert failure.step_index == failed.step.index and failed.step.kind == "approach"
    assert failure.kind is FailureKind.UNREACHABLE and failure.step == failed.step.label
    assert failure.summary() == failed.message and not failure.reason.startswith("step ")
    assert plan.errors == [f"{failed.step.label}: {failure.summary()}"]


def test_on_error_proofs_are_shared_between_jobs_with_the_same_states() -> None:
    """cnc_tend's door and cycle timeouts move nothing: a second job with other
    timeouts verifies its on_error steps from no new state."""
    cell, task = _load("cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml")
    world = CellWorld(cell)
    first = plan_job(world, task, {"door_time": 3.0, "cycle_time": 10.0}, world.q_home_rad,
                     use_cache=False)  # fmt: skip
    assert first.ok, first.errors
    assert first.on_error_steps and all(r.status == "ok" for r in first.task_plan.on_error)
    proofs = dict(world.on_error_memo)
    assert proofs
    second = plan_job(world, task, {"door_time": 5.0, "cycle_time": 20.0}, world.q_home_rad,
                      use_cache=False)  # fmt: skip
    assert second.ok and world.on_error_memo == proofs
    assert [r.message for r in second.task_plan.on_error] == [
        r.message for r in first.task_plan.on_error
    ]
