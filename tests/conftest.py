"""Shared fixtures: paths of the repo's example files."""

from __future__ import annotations

import faulthandler
import os
from pathlib import Path

import pytest

from cellrunner.sim.mujoco_loader import enable_pictures

# The tests render pictures in this process: choose MuJoCo's offscreen GL backend before
# anything imports MuJoCo (it reads MUJOCO_GL once).
GL_BACKEND = enable_pictures()


def pytest_report_header() -> str:
    return f"MuJoCo GL backend for pictures: {GL_BACKEND or 'none'}"


ROOT = Path(__file__).resolve().parent.parent
DEMO_CELL = ROOT / "cells" / "demo_ur5e.yaml"
PICK_PLACE = ROOT / "tasks" / "pick_place.yaml"


@pytest.fixture
def in_repo(monkeypatch):
    """Run with the repository root as the working directory."""
    monkeypatch.chdir(ROOT)
    return ROOT


#: no test may run longer than this: ur_rtde's constructors, for one, wait without a timeout.
#: A hang, not a slow test: on a 2-core machine shared with other builds (load 15) tests
#: that take 20 s alone took over 120 s, and the guard's exit took an xdist worker down
TEST_TIMEOUT_S = 300


@pytest.fixture(autouse=True)
def _hang_guard():
    """Dump every thread's traceback and exit rather than hang CI."""
    faulthandler.dump_traceback_later(TEST_TIMEOUT_S, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


@pytest.fixture(autouse=True)
def _scheduling_guard():
    """A test must leave the test process's thread at the normal scheduling policy: a
    thread left at SCHED_FIFO (a jog session, a twin run in-process) makes every program
    the later tests start real-time too, and a busy one starves the rest (a heartbeat
    test then failed, its serve and flood processes all at SCHED_FIFO)."""
    yield
    if hasattr(os, "sched_getscheduler") and os.sched_getscheduler(0) != os.SCHED_OTHER:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        pytest.fail("the test left its thread at a real-time scheduling policy")


#: test folders and files that run in real time (the virtual controller through ur_rtde,
#: serve, PLC clients, a browser) or bound a wall time: scripts/test runs them one at a
#: time after the others, which it spreads over the cores (they run in simulated time)
WALL_CLOCK = (
    "backends/",
    "commissioning/",
    "plc/",
    "twin/",
    "web/",
    "test_serve",
    "test_fresh_machine.py",
    "cells/test_reference_arms.py",
    "cells/test_reference_cells_ur.py",
    "execution/test_align.py",
    "execution/test_arrive.py",
    "execution/test_cell.py",
    "execution/test_force_jolt.py",
    "execution/test_journal_full_disk.py",
    "execution/test_journal_postgres.py",
    "execution/test_unhold_protective_stop.py",
    "perception/test_sources.py",
    "sim/test_faults.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        where = item.path.relative_to(ROOT / "tests").as_posix()
        if where.startswith(WALL_CLOCK):
            item.add_marker(pytest.mark.wall_clock)
