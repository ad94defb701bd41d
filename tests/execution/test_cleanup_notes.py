"""How on_error's failures are noted: a message that names its step (a timeout, a lost
link, a refused plan) is kept as it is, any other gets the step's label in front; the
ending says which, never the message's wording."""

from __future__ import annotations

from cellrunner.execution.cleanup import Cleanup
from cellrunner.model.codes import ResultCode


def test_a_message_is_labelled_unless_its_ending_names_the_step():
    cleanup = Cleanup([])
    cleanup.first = (ResultCode.NO_PART, "no part")  # as begin() leaves it
    label = "step 7 move 'retreat'"
    cleanup.note(label, ResultCode.STEP_TIMEOUT, f"{label} timed out", names_step=True)
    # worded like a label, yet not one: the ending decides, not the text
    cleanup.note(label, ResultCode.PLACE_FAILED, "step size too large", names_step=False)
    code, text = cleanup.result()
    assert code is ResultCode.NO_PART
    assert text == (f"no part; on_error failed: {label} timed out; {label}: step size too large")


def test_a_refused_plan_lets_the_next_step_run_and_a_fault_does_not():
    cleanup = Cleanup([])
    cleanup.first = (ResultCode.NO_PART, "no part")  # as begin() leaves it
    assert cleanup.note("step 8 move", ResultCode.PLANNING_FAILED, "refused", names_step=False)
    assert not cleanup.note("step 8 move", ResultCode.ESTOP, "e-stop", names_step=False)
