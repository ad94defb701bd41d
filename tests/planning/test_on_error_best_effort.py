"""on_error is best-effort recovery (issue 33): a cleanup step that cannot run from a
state is a warning when the rest of the cleanup, verified from there, still brings the
arm to its end; infeasible only where it cannot; at run time it is skipped and the rest
runs."""

from __future__ import annotations

from cellrunner.execution.cleanup import Cleanup
from cellrunner.model.codes import ResultCode
from tests.planning.on_error_rig import DEMO, task
from tests.rig import main_json

#: a lift the arm cannot make from anywhere (1.5 m up), then a way home that works
SKIPPABLE = "  - lift: 1.5\n  - lift: 0.03\n  - move: home\n"


def test_a_step_that_cannot_run_is_a_warning_when_the_rest_brings_the_arm_home(tmp_path):
    code, out = main_json("check", DEMO, task(tmp_path, SKIPPABLE))
    assert code == 0, out["errors"]
    rows = [(s["index"], s["kind"], s["status"], s["message"]) for s in out["steps"][-3:]]
    assert rows[0][:3] == (7, "lift", "ok")
    assert rows[0][3] == (
        "on_error: verified from 12 states the job can fail in; skipped from 12 of them "
        "(the steps after it bring the arm to its end)"
    )
    assert [r[3] for r in rows[1:]] == ["on_error: verified from 12 states the job can fail in"] * 2
    (warning,) = out["warnings"]
    assert warning.startswith("on_error step 7 lift: from the start: "), warning
    assert warning.endswith(
        "(and from 11 more states); there it is skipped and the steps after it, verified "
        "from where the arm stands, bring the arm to the end of on_error"
    ), warning


def test_the_last_motion_of_on_error_that_cannot_run_is_still_refused(tmp_path):
    code, out = main_json("check", DEMO, task(tmp_path, "  - lift: 0.03\n  - lift: 1.5\n"))
    assert code == 1
    (error,) = out["errors"]
    assert error.startswith("on_error step 8 lift: from the start: "), error
    assert out["warnings"] == []


def test_at_run_time_a_step_that_cannot_be_planned_is_skipped_and_the_rest_runs(tmp_path):
    path = tmp_path / "t.yaml"
    path.write_text(
        "task: t\nsteps:\n  - move: home\n"
        "  - wait_input: {input: part_present, value: true, timeout: 0.2}\n"
        "on_error:\n" + SKIPPABLE
    )
    code, out = main_json("dry-run", DEMO, str(path))
    assert code == 1 and out["result_code"] == int(ResultCode.STEP_TIMEOUT), out
    text = out["result_text"]
    assert text.startswith("input part_present did not read True within 0.2 s; on_error done")
    assert "(skipped: step 3 lift: line leaves the workspace" in text, text
    statuses = {s["index"]: s["status"] for s in out["steps"]}
    # the lift that could not be planned, then the rest: lifted and home
    assert [statuses[i] for i in (3, 4, 5)] == ["failed", "ok", "ok"], out["steps"]


def test_the_cleanup_notes_a_step_that_could_not_be_planned_as_skipped():
    cleanup = Cleanup(steps=[])
    cleanup.first = (ResultCode.STEP_TIMEOUT, "input x did not read True within 1 s")
    assert cleanup.note(
        "on_error step 7 lift", ResultCode.PLANNING_FAILED, "out of reach", names_step=False
    )
    assert cleanup.result() == (
        ResultCode.STEP_TIMEOUT,
        "input x did not read True within 1 s; on_error done (skipped: on_error step 7 "
        "lift: out of reach)",
    )
    assert not cleanup.note(
        "on_error step 8 move", ResultCode.PROTECTIVE_STOP, "stopped", names_step=False
    )
    assert cleanup.result()[1].endswith(
        "on_error failed: on_error step 8 move: stopped (skipped: on_error step 7 lift: out "
        "of reach)"
    )
