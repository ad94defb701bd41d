"""``track`` / ``untrack`` (SPEC section 13): their file form and located errors, their
expansion, the ramps that take up the belt's motion, and what ``check`` proves of the
tracked steps on the reference belt cell (and refuses, naming the speed or the reach)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.errors import InputError
from cellrunner.model.expand import expand, resolve_params
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.belt_ramp import (
    RAMP_ACCEL_MPS2,
    Ramp,
    nominal_start_m,
    ramp_in,
    ramp_out,
)
from tests.cells.spec_written_rig import cli
from tests.conftest import ROOT

CELL = ROOT / "cells" / "conveyor_pick_ur10e.yaml"
TASK = ROOT / "tasks" / "conveyor_pick.yaml"


def _task_errors(tmp_path: Path, steps: str) -> list[str]:
    path = tmp_path / "t.yaml"
    path.write_text(f"task: t\nsteps:\n{steps}")
    with pytest.raises(InputError) as exc:
        load_task(path, load_cell(CELL))
    return [str(d) for d in exc.value.diagnostics]


def test_short_and_bare_forms_load_and_untrack_marks_the_tracked_steps():
    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    steps = expand(task, cell.cell, resolve_params(task.task, {}))
    kinds = [s.kind for s in steps]
    assert kinds[:7] == ["move", "track", "approach", "descend", "grip", "lift", "untrack"]
    assert steps[1].args.conveyor == "belt" and steps[6].extra["conveyor"] == "belt"
    assert [s.extra.get("tracked") for s in steps] == [None] + [None] + ["belt"] * 4 + [None] * (
        len(steps) - 6
    )


@pytest.mark.parametrize(
    ("steps", "line", "message"),
    [
        (
            "  - track: belts\n  - untrack\n",
            3,
            "steps[0].track.conveyor: unknown conveyor 'belts' (did you mean 'belt'?); known: belt",
        ),
        (
            "  - track: belt\n  - move: home\n",
            3,
            "steps[0].track: a track needs an untrack after it (where the arm lets the belt go)",
        ),
        (
            "  - move: home\n  - untrack\n",
            4,
            "steps[1].untrack: an untrack needs a track before it",
        ),
        (
            "  - track: belt\n  - track: belt\n  - untrack\n",
            3,
            "steps[0].track: a track before the untrack of the one before it: untrack first",
        ),
        (
            "  - track: belt\n  - move: tray_slot\n  - untrack\n",
            4,
            "steps[1].move: between track and untrack every target moves with the belt; "
            "'tray_slot' is not on it (frames on it: belt_pick); untrack first",
        ),
        (
            "  - track: belt\n  - move: home\n  - untrack\n",
            4,
            "steps[1].move: between track and untrack every target moves with the belt; a "
            "joint target does not: untrack first",
        ),
    ],
)
def test_task_mistakes_are_located_errors(tmp_path, steps, line, message):
    errors = _task_errors(tmp_path, steps)
    assert errors, "refused"
    where, _, text = errors[0].partition(" error: ")
    assert where.startswith(f"{tmp_path / 't.yaml'}:{line}:"), errors
    assert text == message


# ------------------------------------------------------------------ ramps


def _ends(ramp: Ramp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return ramp.at(np.array([0.0, ramp.duration_s]))


@settings(max_examples=40, deadline=None)
@given(d0=st.floats(-0.3, 0.5), speed=st.floats(0.0, 0.5))
def test_a_ramp_in_joins_rest_to_the_moving_part_within_its_bounds(d0, speed):
    ramp = ramp_in(d0, speed)
    s, v, a = _ends(ramp)
    assert (s[0], v[0], a[0]) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    assert s[1] == pytest.approx(d0 + speed * ramp.duration_s, abs=1e-9)
    assert (v[1], a[1]) == pytest.approx((speed, 0.0), abs=1e-9)
    assert ramp.peaks()[1] <= RAMP_ACCEL_MPS2 + 1e-9
    # its speed is the derivative of its position (finite differences)
    t = np.linspace(0.01, ramp.duration_s - 0.01, 7)
    h = 1e-6
    numeric = (ramp.at(t + h)[0] - ramp.at(t - h)[0]) / (2 * h)
    assert np.allclose(ramp.at(t)[1], numeric, atol=1e-5)


@settings(max_examples=40, deadline=None)
@given(s0=st.floats(-0.3, 0.6), speed=st.floats(0.0, 0.5))
def test_a_ramp_out_brings_the_arm_back_to_rest_at_the_frame(s0, speed):
    ramp = ramp_out(s0, speed)
    s, v, a = _ends(ramp)
    assert (s[0], v[0], a[0]) == pytest.approx((s0, speed, 0.0), abs=1e-9)
    assert (s[1], v[1], a[1]) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    assert ramp.peaks()[1] <= RAMP_ACCEL_MPS2 + 1e-9


def test_the_earliest_start_meets_the_part_at_belt_speed_without_catching_up():
    d0 = nominal_start_m(0.3, -0.25)
    ramp = ramp_in(d0, 0.3)
    _, v, _ = ramp.at(np.linspace(0.0, ramp.duration_s, 50))
    assert d0 < 0 and np.all(np.diff(v) >= -1e-9)  # speeds up only
    assert float(v.max()) == pytest.approx(0.3, abs=1e-6)  # never faster than the belt
    assert nominal_start_m(0.3, -0.01) == -0.01  # never before the window


# ------------------------------------------------------------------ check


@pytest.mark.parametrize(
    ("cell", "task", "name", "speed_max"),
    [
        (CELL, TASK, "belt", 0.3),
        (
            ROOT / "cells" / "round_table_ur10e.yaml",
            ROOT / "tasks" / "round_table_pick.yaml",
            "table",
            0.2,
        ),
    ],
    ids=["belt", "round-table"],
)
def test_check_proves_the_reference_conveyors_and_says_how_late_a_pick_may_start(
    cell, task, name, speed_max
):
    code, out = cli("check", str(cell), str(task))
    assert code == 0, out["errors"]
    (belt,) = out["conveyors"]
    assert belt["name"] == name and belt["error"] is None
    assert belt["cases_proved"] == belt["cases_checked"] >= 30
    lo, hi = belt["window_m"]
    assert lo <= belt["latest_start_m"] < hi
    assert belt["reachable_m"] == [[lo, hi]]
    # both rounded in the JSON: parts per minute to 0.01, the cycle to 0.1 ms
    assert belt["parts_per_minute"] == pytest.approx(60 / out["cycle_time_s"], abs=0.0051)
    assert belt["min_pitch_m"] == pytest.approx(speed_max * out["cycle_time_s"], rel=1e-3)


def _variant(tmp_path: Path, **replace: str) -> Path:
    text = CELL.read_text().replace("tasks: {1: tasks/conveyor_pick.yaml}\n", "")
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "cell.yaml"
    path.write_text(text)
    return path


def test_a_pick_too_fast_for_the_window_is_refused_naming_the_speed_that_works(tmp_path):
    fast = _variant(tmp_path, **{"speed_max: 0.30": "speed_max: 1.2"})
    code, out = cli("check", str(fast), str(TASK), "--no-cache")
    assert code == 1
    (belt,) = out["conveyors"]
    assert belt["latest_start_m"] is None and 0 < belt["speed_ok_mps"] < 1.2
    (error,) = out["errors"]
    assert error.startswith("conveyor 'belt': the pick cannot be made at 1.2 m/s anywhere in")
    assert error.endswith(f"it can at {belt['speed_ok_mps']:.3f} m/s")
    # ... and at that speed it is proved
    ok = _variant(tmp_path, **{"speed_max: 0.30": f"speed_max: {belt['speed_ok_mps']:.3f}"})
    code, out = cli("check", str(ok), str(TASK), "--no-cache")
    assert code == 0, out["errors"]
    assert out["conveyors"][0]["latest_start_m"] is not None


def test_a_window_out_of_reach_is_an_error_naming_what_is_reachable(tmp_path):
    far = _variant(
        tmp_path,
        **{
            "from: [0.75, -0.9, 0.80], to: [0.75, 0.9, 0.80]": "from: [0.75, -3.9, 0.80], to: [0.75, 3.9, 0.80]",
            "window: [-0.25, 0.40]": "window: [1.8, 2.6]",
        },
    )
    code, out = cli("check", str(far), str(TASK), "--no-cache")
    assert code == 1
    (belt,) = out["conveyors"]
    assert belt["reachable_m"] == []
    assert out["errors"] == [
        "conveyor 'belt': the arm reaches none of the window [+1.800, +2.600] m (the pick's "
        "grip pose moved along the belt has no IK solution anywhere in it)"
    ]


def test_a_task_without_a_track_has_no_conveyor_proof():
    code, out = cli(
        "check", str(ROOT / "cells" / "demo_ur5e.yaml"), str(ROOT / "tasks" / "home.yaml")
    )
    assert code == 0 and out["conveyors"] == []


def test_a_place_onto_the_moving_belt_is_proved_too(tmp_path):
    cell = _variant(tmp_path, **{"mass: 0.2, at: belt_pick}": "mass: 0.2, at: tray_slot}"})
    task = tmp_path / "onto_belt.yaml"
    task.write_text(
        "task: onto_belt\n"
        "steps:\n"
        "  - pick: {at: tray_slot, approach: 0.1, grip: {confirm: jaws_closed}}\n"
        "  - move: above_belt\n"
        "  - track: belt\n"
        "  - place: {at: belt_pick, approach: 0.08}\n"
        "  - untrack\n"
        "  - move: home\n"
    )
    code, out = cli("check", str(cell), str(task), "--no-cache")
    assert code == 0, out["errors"]
    (belt,) = out["conveyors"]
    assert belt["what"] == "place" and belt["cases_proved"] == belt["cases_checked"]
    assert belt["latest_start_m"] is not None


def test_a_rehearsal_picks_the_block_off_the_moving_belt_into_the_tray():
    """The twin's belt carries the block past the eye; the arm follows it, grips it on the
    move and puts it in the tray: the job ends 0, the tracked steps run within track."""
    code, out = cli("dry-run", str(CELL), str(TASK))
    assert code == 0, out["errors"]
    kinds = [(s["kind"], s["status"]) for s in out["steps"][:7]]
    assert kinds == [
        ("move", "ok"),
        ("track", "ok"),
        ("approach", "ok"),
        ("descend", "ok"),
        ("grip", "ok"),
        ("lift", "ok"),
        ("untrack", "ok"),
    ]
    x, y, z = out["parts_end_m"]["block"]
    # tray_slot is the TCP at the block's centre: 0.35, 0.55; the block rests on the tray
    # (top at 0.80 m) with its centre 25 mm up
    assert np.hypot(x - 0.35, y - 0.55) < 0.005 and abs(z - 0.825) < 0.003


def test_what_the_proof_passes_at_8_ms_holds_at_the_controller_rate():
    """The proof samples every 8 ms; the same cases resampled every 2 ms (the e-Series
    controller's period) keep reach, limits and clearance too, at the earliest start and
    at the latest start the proof reported, at top speed."""
    from cellrunner.planning.belt_ramp import ramp_bounds
    from cellrunner.planning.task_plan import plan_task
    from cellrunner.planning.tracked_piece import still_piece, tracked_stretches
    from cellrunner.planning.tracking import SAMPLE_S, prove_case, prove_tracking
    from cellrunner.planning.world import CellWorld

    cell = load_cell(CELL)
    task = load_task(TASK, cell)
    world = CellWorld(cell)
    plan = plan_task(
        world, expand(task, cell.cell, resolve_params(task.task, {})), world.q_home_rad
    )
    (proof,) = prove_tracking(world, plan)
    assert proof.latest_start_m is not None and SAMPLE_S == 0.008
    ((name, rows),) = tracked_stretches(plan)
    belt = cell.cell.conveyors[name]
    piece = still_piece(world, plan, rows, 0.002)
    v = float(belt.speed_max)
    earliest = nominal_start_m(v, float(belt.window[0]), ramp_bounds(belt.path))
    for start in (earliest, proof.latest_start_m):
        case = prove_case(world, belt, piece, v, start)
        assert case.ok, case.reason
