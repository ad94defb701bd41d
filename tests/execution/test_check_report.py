"""check's failures are data: slots are grouped by what failed (kind, step, the bodies in
the way), so rewording a message changes the text printed, never the groups."""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import pickle
from typing import Any

import pytest

from cellrunner.cli.main import main
from cellrunner.execution.check_report import group_failures
from cellrunner.model.body import Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.planning import blockers
from tests.conftest import ROOT

CONVEYOR = ROOT / "tests" / "data" / "diagnostics" / "conveyor_near_shoulder.yaml"
TASK = ROOT / "tasks" / "pick_place.yaml"
TABLE = Body(BodyKind.FIXTURE, "table")
WALL = Body(BodyKind.FIXTURE, "wall")


def _failure(reason: str, *bodies: Body, step: int = 4, kind: FailureKind = FailureKind.COLLISION):
    return Failure(
        kind,
        reason,
        blockers=tuple(Blocker(b, -0.001 * step) for b in bodies),
        fix="fix: move it",
        step_index=step,
        step=f"step {step} descend",
    )


def test_slots_failing_alike_group_whatever_their_text_says() -> None:
    failures = [
        ("slot", 3, _failure("the tool collides with the table, three mm deep", TABLE)),
        ("slot", 5, _failure("TOOL MEETS TABLE (FIVE MILLIMETRES)", TABLE)),
        ("slot", 4, _failure("anything at all", TABLE)),
        ("slot", 7, _failure("the tool collides with the table, three mm deep", WALL)),
        ("slot", 8, _failure("the tool collides with the table", TABLE, step=6)),
        ("slot", 9, _failure("same", TABLE, kind=FailureKind.SUPPORT)),
    ]
    groups = group_failures(failures)
    assert [(g.param, g.values) for g in groups] == [
        ("slot", [3, 4, 5]),
        ("slot", [7]),
        ("slot", [8]),
        ("slot", [9]),
    ]
    # shown with the first slot's failure; the text is made from its fields
    assert groups[0].text() == (
        "slots 3-5: step 4 descend: the tool collides with the table, three mm deep; fix: move it"
    )
    assert groups[0].to_json()["kind"] == "collision"
    assert groups[0].to_json()["blockers"] == [
        {"kind": "fixture", "name": "table", "distance_m": pytest.approx(-0.004)}
    ]


def test_a_failure_keeps_its_fields_through_json_and_pickle() -> None:
    """What the plan files and the sweep's child process carry."""
    failure = _failure("blocked", TABLE, Body(BodyKind.WAITING_PART, "block"))
    assert Failure.from_json(json.loads(json.dumps(failure.to_json()))) == failure
    back = pickle.loads(pickle.dumps(failure))
    assert back == failure and back.bodies[1].kind is BodyKind.WAITING_PART


def _check() -> dict[str, Any]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(["check", str(CONVEYOR), str(TASK), "--json", "--no-cache"])
    assert code == 1
    result: dict[str, Any] = json.loads(out.getvalue())
    return result


_DIGITS = ["zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine"]


def _spelled(value: float) -> str:
    return "-".join(_DIGITS[int(d)] for d in f"{abs(value):.1f}" if d.isdigit())


def test_rewording_a_message_template_keeps_checks_groups(monkeypatch) -> None:
    """The conveyor near the shoulder refuses all twelve slots alike. A template that
    writes its numbers as words, and a word that changes each time it is used (which no
    number-masking regex sees through), changes every message, and the groups stay."""
    before = _check()
    groups = [(g["param"], g["slots"], g["kind"], g["step"]) for g in before["failed_slots"]]
    assert groups == [("slot", list(range(12)), "collision", 2)]
    assert {b["name"] for b in before["failed_slots"][0]["blockers"]} >= {"conveyor"}

    uses = itertools.count()

    def reworded(c: Any) -> str:
        nth = _spelled(next(uses))
        return f"{c.a} sits {_spelled(c.distance_m * 1000)} millimetres into {c.b} ({nth})"

    monkeypatch.setattr(blockers, "_short", reworded)
    after = _check()
    assert [(g["param"], g["slots"], g["kind"], g["step"]) for g in after["failed_slots"]] == groups
    assert after["errors"] != before["errors"]
    assert "millimetres into fixture 'conveyor'" in after["failed_slots"][0]["error"]
    # the slots' texts now differ beyond their numbers: a text key would split them
    assert len({e.split(": ", 1)[1] for e in after["errors"][1:]}) > 1
