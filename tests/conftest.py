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
#: serve, PLC clients, a browser): scripts/test runs them after the tests that run in
#: simulated time, each round spread over the cores, so that no real-time test shares
#: the machine with a test that keeps a core busy
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


#: the tests (files, or file::test) that bound a wall time: a heartbeat's or a tick's
#: gap, a stream's rate, how late a stop comes. scripts/test runs them last, one at a
#: time, so that what they measure is cellrunner, not a neighbour
TIME_BOUND = (
    "backends/test_ur_backend.py::test_streams_an_approved_trajectory_and_tracks_it",
    "commissioning/test_jog.py::test_jog_stops_before_the_wall_and_before_the_wrist",
    # four times the set-points in four times the controller's time, measured as they arrive
    "commissioning/test_run_pace.py::test_quarter_speed_streams_the_approved_set_points_four",
    "commissioning/test_servo_udp.py::test_a_program_streams_twists_the_arm_follows",
    "commissioning/test_servo_watched.py",
    "execution/test_cell.py::test_rearming_after_an_estop_is_polled_by_tick",
    "execution/test_unhold_protective_stop.py",
    "plc/test_modbus.py::test_cell_heartbeat_increments_at_least_every_200ms",
    "plc/test_opcua.py::test_encrypted_user_session_runs_a_job_and_gets_the_completion",
    "plc/test_opcua_login_flood.py",
    "test_serve_login_flood.py",
    "test_stop_on_signal.py",
    "twin/test_conveyor_twin.py",  # the engine keeps pace with a belt the controller counts
    # ... or the PLC counts, its writes timed by the engine's clock
    "twin/test_plc_encoder_on_run.py::test_serve_on_the_arm_tracks_a_belt_the_plc_counts",
    "plc/test_plc_encoders_serve.py",
    "twin/test_serve_faults.py",
    "twin/test_ur_rtde_client.py::test_rtde_streams_500_hz_on_e_series",
    "twin/test_ur_rtde_client.py::test_movej_reaches_target_with_trapezoid_timing",
    "twin/test_ur_rtde_client.py::test_cb3_controller_answers_as_cb3_at_125_hz",
    "twin/test_ur_rtde_client.py::test_move_until_contact_stops_on_tool_force",
    "web/test_live_server.py::test_serve_ends_within_2_s_of_sigterm_with_five_live_views_open",
    "web/test_live_view_browser.py",  # the page within one update of the backend
    "web/test_live_view_firefox.py",
    "web/test_obstructed_browser.py",  # the page shows the wait while the tote is there
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        where = item.path.relative_to(ROOT / "tests").as_posix()
        if f"{where}::{item.name}".startswith(TIME_BOUND):
            item.add_marker(pytest.mark.time_bound)
        elif where.startswith(WALL_CLOCK):
            item.add_marker(pytest.mark.wall_clock)
