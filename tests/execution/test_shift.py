"""A shift in rehearsal (SPEC 13): the shift's bookkeeping on timelines given here (the
figures' definitions, slots, faults drawn, seeds), then `dry-run --shift` on the demo cell
in the twin: the same seed gives the same numbers, and a failed job rehearsed alone with
its faults gives the shift's result."""

from __future__ import annotations

import json
import random
import shlex
from typing import Any

import pytest

from cellrunner.errors import UsageError
from cellrunner.execution.shift import (
    ShiftPlan,
    ShiftRehearsal,
    Timeline,
    draw_faults,
    eligible_steps,
    parse_duration,
)
from cellrunner.model.job_steps import job_steps
from cellrunner.model.load import load_cell, load_task
from tests.conftest import ROOT
from tests.rig import cli, main_json

DEMO = ROOT / "cells" / "demo_ur5e.yaml"
PICK_PLACE = ROOT / "tasks" / "pick_place.yaml"
BELT_CELL = ROOT / "cells" / "conveyor_pick_ur10e.yaml"
BELT_TASK = ROOT / "tasks" / "conveyor_pick.yaml"


def demo_steps(slot: int = 0) -> list[Any]:
    cell = load_cell(DEMO)
    return job_steps(load_task(PICK_PLACE, cell), cell.cell, {"slot": slot})


def timeline(code: int, cycle_s: float) -> Timeline:
    return Timeline(
        code, "OK" if code == 0 else f"code {code}", cycle_s, 0, (("move", "home", 1.0),)
    )


def shift_of(plan: ShiftPlan, faulted: dict[str, Timeline]) -> tuple[ShiftRehearsal, list[Any]]:
    """Three slots of 10 s jobs; a faulted job's timeline by its first fault's name."""
    calls: list[Any] = []
    slots = [{"slot": i} for i in range(3)]

    def clean(jobs):
        calls.append(("clean", len(jobs)))
        return [timeline(0, 10.0) for _ in jobs]

    def faulted_job(params, drawn):
        calls.append(("faulted", params["slot"], drawn))
        return faulted[drawn[0][0]]

    steps = demo_steps()
    return ShiftRehearsal(plan, slots, lambda p: steps, clean, faulted_job), calls


def test_a_shift_without_faults_is_back_to_back_jobs_through_the_slots():
    shift, calls = shift_of(ShiftPlan(100.0), {})
    report = shift.run()
    assert len(report.jobs) == 10  # 10 s each, the last started at 90 s
    assert [j.params["slot"] for j in report.jobs] == [0, 1, 2] * 3 + [0]
    assert report.parts_good == 10 and report.availability == 1.0
    assert report.mtbf_s is None and report.mttr_s is None
    assert calls == [("clean", 3)]  # each slot's job rehearsed once
    out = report.to_json(lambda j: "")
    assert out["parts_per_hour"] == 360.0 and out["results"] == {"0": 10}


def test_a_part_every_feed_interval_paces_the_line():
    report = shift_of(ShiftPlan(100.0, feed_every_s=25.0), {})[0].run()
    assert [j.start_s for j in report.jobs] == [0.0, 25.0, 50.0, 75.0]


def test_a_job_that_stops_the_line_costs_its_time_and_the_operators():
    plan = ShiftPlan(1000.0, {"protective_stop": 1.0}, seed=1, operator_s=40.0)
    shift, calls = shift_of(plan, {"protective_stop": timeline(100, 5.0)})
    report = shift.run()
    # every job fails (rate 1): 45 s each, the slot never moves on
    assert len(report.jobs) == 23 and report.failures == 23
    assert {j.params["slot"] for j in report.jobs} == {0}
    assert report.downtime_s == 1000.0  # capped at the shift
    assert report.availability == 0.0 and report.mttr_s == pytest.approx(1000.0 / 23)
    faulted = [c for c in calls if c[0] == "faulted"]
    assert len(faulted) == len({c[2] for c in faulted})  # each distinct (slot, faults) once


def test_a_job_that_completes_nok_lets_the_line_go_on():
    plan = ShiftPlan(100.0, {"grip_miss": 1.0}, seed=1, operator_s=40.0)
    report = shift_of(plan, {"grip_miss": timeline(1, 10.0)})[0].run()
    assert len(report.jobs) == 10 and report.parts_good == 0 and report.failures == 0
    assert report.availability == 1.0  # no stop: a loss of good parts, not of time
    out = report.to_json(lambda j: f"replay {j.number}")
    assert [r["kind"] for r in out["replay"]] == ["grip_miss -> 1"]
    assert out["replay"][0]["command"] == "replay 1" and out["parts_bad"] == 10


def test_figures_of_a_mixed_shift():
    plan = ShiftPlan(3600.0, {"estop": 0.05}, seed=7, operator_s=60.0)
    report = shift_of(plan, {"estop": timeline(105, 6.0)})[0].run()
    failures = [j for j in report.jobs if j.timeline.code == 105]
    assert failures and report.failures == len(failures)
    assert report.downtime_s == pytest.approx(len(failures) * 66.0)
    assert report.mttr_s == pytest.approx(66.0)
    assert report.mtbf_s == pytest.approx((3600.0 - report.downtime_s) / len(failures))
    assert report.availability == pytest.approx(1 - report.downtime_s / 3600.0)
    assert sum(report.results().values()) == len(report.jobs)


def test_the_same_seed_draws_the_same_faults_and_another_seed_others():
    steps = demo_steps()
    rates = {"grip_miss": 0.3, "protective_stop": 0.3, "part_slip": 0.3}

    def draws(seed):
        rng = random.Random(seed)
        return [draw_faults(rng, rates, steps) for _ in range(200)]

    assert draws(5) == draws(5)
    assert draws(5) != draws(6)
    # each fault at a step where it can happen
    kinds = {s.index: s.kind for s in steps}
    for job in draws(5):
        for fault, index in job:
            assert index in eligible_steps(fault, steps)
            if fault == "grip_miss":
                assert kinds[index] == "grip"


def test_a_slip_can_only_strike_while_a_part_is_carried():
    steps = demo_steps()
    by_index = {s.index: s.kind for s in steps}
    slips = eligible_steps("part_slip", steps)
    assert slips and all(by_index[i] in ("lift", "approach", "descend", "move") for i in slips)
    grip = next(s.index for s in steps if s.kind == "grip")
    release = next(s.index for s in steps if s.kind == "release")
    assert all(grip < i < release for i in slips)


@pytest.mark.parametrize(
    ("text", "seconds"), [("8h", 28800.0), ("90m", 5400.0), ("1h30m", 5400.0), ("45", 45.0)]
)
def test_durations(text, seconds):
    assert parse_duration(text) == seconds


@pytest.mark.parametrize("text", ["", "0", "-3h", "8x", "h"])
def test_bad_durations_say_the_forms(text):
    with pytest.raises(UsageError, match="8h"):
        parse_duration(text)


def test_a_faults_file_with_an_unknown_fault_is_a_located_error(tmp_path):
    faults = tmp_path / "faults.yaml"
    faults.write_text("grip_miss: 0.01\ngrip_mis: 0.02\nestop: 2\n")
    r = cli("dry-run", str(DEMO), str(PICK_PLACE), "--shift", "1h", "--faults", str(faults))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert lines[0].endswith(
        "faults.yaml:2:1: error: unknown fault 'grip_mis'; known: grip_miss, part_slip, "
        "protective_stop, estop, robot_disconnect, plc_disconnect"
    ), lines
    assert lines[1].endswith(
        "faults.yaml:3:8: error: estop: 2 is not a rate per job; give 0..1 (e.g. 0.005)"
    ), lines
    assert "Traceback" not in r.stderr


# ------------------------------------------------------------------ in the twin


@pytest.fixture(scope="module")
def rehearsed_shift(tmp_path_factory) -> tuple[dict[str, Any], list[str]]:
    faults = tmp_path_factory.mktemp("shift") / "faults.yaml"
    faults.write_text("grip_miss: 0.08\npart_slip: 0.05\n")
    args = ["dry-run", str(DEMO), str(PICK_PLACE), "--shift", "6m", "--faults", str(faults)]
    code, out = main_json(*args, "--seed", "11")
    assert code == 0, out
    return out, args


def test_a_shift_of_the_demo_in_the_twin(rehearsed_shift):
    out, _ = rehearsed_shift
    for key in ("jobs", "parts_good", "parts_bad", "parts_per_hour", "availability"):
        assert key in out
    assert out["jobs"] == out["parts_good"] + out["parts_bad"] == sum(out["results"].values())
    assert 40 <= out["jobs"] <= 60, out["jobs"]  # the demo's cycle is about 7 s
    assert out["parts_per_hour"] == pytest.approx(out["parts_good"] * 10, abs=0.1)
    assert out["parts_bad"] > 0 and out["replay"], out  # the rates make some fail
    assert out["slowest_steps"][0]["mean_s"] >= out["slowest_steps"][-1]["mean_s"] > 0
    assert out["rehearsed_jobs"] < out["jobs"]


def test_the_same_seed_gives_the_same_numbers(rehearsed_shift):
    first, args = rehearsed_shift
    code, again = main_json(*args, "--seed", "11")
    assert code == 0
    first, again = dict(first), dict(again)
    first.pop("wall_s"), again.pop("wall_s")
    assert again == first


def test_a_failed_job_rehearsed_alone_with_its_faults_gives_the_shifts_result(rehearsed_shift):
    out, _ = rehearsed_shift
    replay = out["replay"][0]
    words = shlex.split(replay["command"])
    assert words[:2] == ["cellrunner", "dry-run"]
    code, alone = main_json(*words[1:])
    assert code == 1, alone
    assert (alone["result_code"], alone["result_text"]) == (
        replay["result_code"],
        replay["result_text"],
    )
    assert alone["params"] == replay["params"]
    assert json.dumps(alone["injected"]) == json.dumps(replay["inject"])


def test_a_belt_cells_shift_is_paced_by_its_feed():
    """The reference belt cell's twin feeds a block every 8 s and its job takes about 7 s:
    the shift takes its pace from the feed (no more than 450 parts an hour), unless told
    that a part is always waiting."""
    args = ["dry-run", str(BELT_CELL), str(BELT_TASK), "--shift", "4m"]
    code, fed = main_json(*args)
    assert code == 0, fed
    assert fed["parts_good"] == fed["jobs"] > 0
    assert fed["parts_per_hour"] <= 3600 / 8.0 + 15  # the first part is there at 0 s
    code, waiting = main_json(*args, "--feed-every", "0")
    assert code == 0, waiting
    assert waiting["jobs"] > fed["jobs"]
