"""The line-like reference cell (cells/cnc_tray_ur10.yaml, issue 27): a CB3 UR10 with a
3 x 4 tray, two grippers and a changer, a force-limited vise insert, door and cycle IO
and on_error. ``check`` proves every slot and on_error from every state; ``dry-run``
runs the job to the end with the blank at the outfeed."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT

CELL, TASK = "cells/cnc_tray_ur10.yaml", "tasks/cnc_tray.yaml"


def _cli(*args: str) -> tuple[int, dict]:
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", *args, "--json"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        env={**os.environ, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1"},
    )
    assert r.returncode in (0, 1), r.stderr[-3000:]
    return r.returncode, json.loads(r.stdout)


def test_check_proves_every_slot_and_on_error_from_every_state():
    code, out = _cli("check", CELL, TASK, "--no-cache")
    assert code == 0 and out["ok"], out["errors"]
    assert out["slots_checked"]["slot"] == list(range(12))
    kinds = [s["kind"] for s in out["steps"]]
    assert kinds.count("tool_unlock") == 2 and "insert" in kinds
    on_error = [s for s in out["steps"] if s["index"] > 45]  # the job has 45 steps
    assert len(on_error) == 3
    assert all(s["message"].startswith("on_error: verified from ") for s in on_error)


def test_dry_run_inserts_the_blank_and_unloads_it_to_the_outfeed():
    code, out = _cli("dry-run", CELL, TASK, "-p", "slot=0")
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    x, y, z = out["parts_end_m"]["blank"]
    assert (x, y) == pytest.approx((0.20, 0.40), abs=0.005)  # the outfeed
    assert z == pytest.approx(0.93, abs=0.004)  # standing on the table
