"""Whole runs in rehearsal (SPEC section 12): ``dry-run --slots all`` or ``-p slot=A..B``
runs the task once per value in one twin, parts staying where they were put, a part fed
before each job; a row (JSON: a job) per job. And a fault injected into a short straight
step strikes in that step."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from cellrunner.cli.faults import Injection
from tests.cells.reference import PALLETIZER
from tests.conftest import ROOT
from tests.rig import dry_run

DEMO = ("cells/demo_ur5e.yaml", "tasks/pick_place.yaml")


def test_a_range_of_slots_runs_in_one_twin_on_the_earlier_slots_parts():
    """Slots 4 and 5 of the palletizer (layer 2), rehearsed in a row: slots 0-3 are in
    place before the first, the conveyor brings a carton before each (the part the task
    picks: the cell has no sim: feed), and each carton stays where its job put it."""
    out = dry_run(*PALLETIZER, "-p", "slot=4..5")
    assert out["ok"] and out["param"] == "slot"
    assert [(j["params"]["slot"], j["result_code"]) for j in out["jobs"]] == [(4, 0), (5, 0)]
    assert all(j["cycle_time_s"] > 5.0 and j["steps"] for j in out["jobs"])
    ends = out["parts_end_m"]
    assert sorted(n for n in ends if "@" in n) == [f"carton@slot={k}" for k in range(4)]
    # the carton of the cell file went to slot 4, the one fed after it to slot 5
    assert ends["carton"] == pytest.approx([0.69, 0.285, 0.29], abs=0.003)
    assert ends["carton#1"] == pytest.approx([0.69, 0.115, 0.29], abs=0.003)


def test_a_whole_run_prints_a_row_per_job():
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run", *DEMO, "--slots", "0..1"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        env={**os.environ, "COLUMNS": "120", "OMP_NUM_THREADS": "1"},
    )
    assert r.returncode == 0, r.stderr[-2000:]
    shown = r.stderr  # the terminal's (human output goes to stderr)
    assert "pick_place on demo-ur5e, 2 jobs in one twin" in shown
    rows = [line for line in shown.splitlines() if "OK" in line and "│" in line]
    assert len(rows) == 2, shown
    assert "2 of 2 jobs OK" in shown


@pytest.mark.parametrize(
    "argv, message",
    [
        (("--slots", "all", "-p", "slot=1..2"), "one whole run at a time"),
        (("-p", "slot=5..3"), "slot=5..3: the values must rise within 0..11"),
        (("-p", "slot=0..x"), "write all, a value, or FIRST..LAST (within 0..11)"),
        (("--slots", "0..1", "--report", "r"), "--report rehearses one job"),
    ],
)
def test_a_bad_whole_run_is_one_line_and_exit_2(argv, message):
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run", *DEMO, *argv],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert message in r.stderr and "Traceback" not in r.stderr


def test_slots_needs_a_task_with_a_pattern():
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run", "cells/demo_ur5e.yaml"]
        + ["tasks/home.yaml", "--slots", "all"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )
    assert r.returncode == 2
    assert "--slots needs a task with one pattern param (found: none)" in r.stderr


def test_a_delayed_fault_strikes_halfway_through_a_short_step():
    stop = Injection("protective_stop", 3, "protective_stop@descend")
    assert stop.delay_within_s(None) == stop.delay_within_s(2.0) == 0.3
    assert stop.delay_within_s(0.26) == pytest.approx(0.13)
    assert Injection("grip_miss", 4, "grip_miss@grip").delay_within_s(0.2) == 0.0


def test_a_protective_stop_in_a_short_descend_is_logged_in_that_descend():
    """The demo's descend lasts 0.26 s, under the 0.3 s a stop waits into its step: it
    struck in the grip after it. Now the descend holds the 5 s of the stop."""
    out = dry_run(*DEMO, "--inject", "protective_stop@descend")
    assert out["result_code"] == 0, out["result_text"]
    steps = {s["index"]: s for s in out["steps"]}
    assert steps[3]["kind"] == "descend" and steps[3]["duration_s"] > 5.0
    assert steps[4]["kind"] == "grip" and steps[4]["duration_s"] < 1.0
