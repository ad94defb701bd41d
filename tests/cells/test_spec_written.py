"""Cells written from SPEC.md alone by someone who did not write the engine (issue 24, item
7), in tests/cells/spec_written/, one arm each: a CB3 UR10 tending a CNC with two tools and
a vise insert, a ceiling-mounted UR5e picking from a conveyor past a waiting box, a UR20
palletizing tall cartons onto two pallets in two layers, a UR3e driving a 4-hole screw
pattern, a CB3 UR3 inserting a 20 mm peg into a 24 mm (and 21 mm) hole, a UR10e reaching
through a guard wall's window, a CB3 UR5 aligning on a marker before its pick (the UR16e
watched cell is in test_spec_written_watch.py). Each has a part deliberately off its frame
(``*_off_frame.yaml``, or the align cell's rehearsal offset) and a deliberately wrong place
(a task that lets go over nothing, past an edge, or into a stale frame).

What is asserted is what a line engineer reads in the SPEC: a correct job checks and
rehearses to 0 with its part where the task put it; the twin never says 0 for a part
that is not where the task put it (section 11, "Places that fail"); faults happen to the
part really held; check refuses what the twin would stop; bad input is one located line.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cells.spec_written_rig import HERE, cell, cli, task


def params(*pairs: str) -> list[str]:
    return [arg for pair in pairs for arg in ("-p", pair)]


def place_failed_mm(out: dict) -> float:
    """The distance (mm) a 'place failed' result measured."""
    found = re.search(r"is ([0-9.]+) mm", out["result_text"])
    assert found, out["result_text"]
    return float(found.group(1))


# Correct jobs: (cell, task, params, where each moved part's middle must end, world m).
CORRECT = {
    "ceiling_ur5e_conveyor": (
        "ceiling_conveyor_ur5e",
        "conveyor_pick",
        (),
        {"box": (0.0, 0.45, 0.925)},
    ),
    "ur20_left_pallet_slot0": (
        "two_pallet_ur20",
        "pallet_left",
        ("slot=0",),
        {"carton": (-0.205, 1.155, 0.244)},
    ),
    "ur20_right_pallet_slot3": (
        "two_pallet_ur20",
        "pallet_right",
        ("slot=3",),
        {"carton": (0.205, -1.155, 0.244)},
    ),
    "ur3e_bracket_to_nest": ("screwing_ur3e", "bracket", (), {"bracket": (0.12, 0.25, 0.805)}),
    "ur3_tight_peg_24mm_hole": ("peg_ur3", "peg", (), {"peg": (0.30, 0.15, 0.86)}),
    "ur3_tighter_peg_21mm_hole": ("peg_ur3_21mm", "peg", (), {"peg": (0.30, 0.15, 0.86)}),
    "ur3e_screw_hole3_of_pattern": (
        "screwing_ur3e",
        "screw",
        ("hole=3",),
        {"bracket": (0.25, -0.15, 0.805)},
    ),
    "ur3e_screw_one_with_on_error": (
        "screwing_ur3e",
        "screw_one",
        (),
        {"bracket": (0.25, -0.15, 0.805)},
    ),
    "ur10_cnc_two_tools_vise_insert": ("cnc_ur10", "cnc", (), {"blank": (0.40, -0.35, 0.93)}),
    "ur10e_through_a_guard_window": (
        "guard_window_ur10e",
        "unload_press",
        (),
        {"block": (0.35, -0.35, 0.925)},
    ),
}


@pytest.mark.parametrize("case", CORRECT.values(), ids=CORRECT.keys())
def test_a_correct_job_checks_and_rehearses_to_0_with_its_part_where_the_task_put_it(case):
    cell_name, task_name, pairs, ends = case
    code, out = cli("check", cell(cell_name), task(task_name), *params(*pairs))
    assert (code, out["ok"]) == (0, True), out["errors"]
    code, out = cli("dry-run", cell(cell_name), task(task_name), *params(*pairs))
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    for part, xyz in ends.items():
        assert math.dist(out["parts_end_m"][part], xyz) < 0.005, (part, out["parts_end_m"][part])


# A part off its frame: (cell, task, params, the least offset the result must report, mm;
# None where the result is a failed insert, which reports its depth).
OFF_FRAME = {
    "ceiling_ur5e_box_12mm_12mm_3deg": (
        "ceiling_conveyor_ur5e_off_frame",
        "conveyor_pick",
        (),
        8.0,
    ),
    "ur20_carton_150mm_along_belt": (
        "two_pallet_ur20_off_frame",
        "pallet_left",
        ("slot=0",),
        100.0,
    ),
    "ur3e_bracket_10mm_4deg": ("screwing_ur3e_off_frame", "bracket", (), 7.0),
    "ur10_blank_12mm_into_vise": ("cnc_ur10_off_frame", "cnc", (), None),
    "ur10e_block_15mm_6deg_behind_the_wall": (
        "guard_window_ur10e_off_frame",
        "unload_press",
        (),
        10.0,
    ),
    "ur3_peg_8mm_off_hole": ("peg_ur3_off_frame", "peg", (), None),
}


@pytest.mark.parametrize("case", OFF_FRAME.values(), ids=OFF_FRAME.keys())
def test_a_part_off_its_frame_is_never_0_but_a_failed_place_with_its_offset(case):
    cell_name, task_name, pairs, least_mm = case
    code, out = cli("dry-run", cell(cell_name), task(task_name), *params(*pairs))
    assert (code, out.get("result_code")) == (1, 3), (out.get("result_text"), out["errors"])
    if least_mm is not None:
        assert out["result_text"].startswith("place failed"), out["result_text"]
        assert place_failed_mm(out) >= least_mm, out["result_text"]


# A wrong place on a correct cell: (cell, task, params).
WRONG_PLACE = {
    "ceiling_ur5e_past_the_outfeed_table": (
        "ceiling_conveyor_ur5e",
        "conveyor_pick_past_table",
        (),
    ),
    "ur20_carton_mostly_off_the_pallet": ("two_pallet_ur20", "pallet_left_overhang", ("slot=2",)),
    "ur3e_bracket_beside_the_bench": ("screwing_ur3e", "bracket_beside_bench", ()),
    "ur10_part_past_the_table_edge": ("cnc_ur10", "cnc_past_edge", ()),
    "ur10e_block_past_the_table_edge": ("guard_window_ur10e", "unload_press_past_table", ()),
    "ur3_peg_into_a_stale_hole_frame": ("peg_ur3", "peg_as_taught", ()),
}


@pytest.mark.parametrize("case", WRONG_PLACE.values(), ids=WRONG_PLACE.keys())
def test_a_wrong_place_is_never_0(case):
    """Refused by check (dry-run checks first) or failed in the twin; never OK, and never
    refused as bad input (the files are valid)."""
    cell_name, task_name, pairs = case
    code, out = cli("dry-run", cell(cell_name), task(task_name), *params(*pairs))
    assert code == 1, (code, out["errors"])
    assert isinstance(out["result_code"], int) and out["result_code"] != 0, out["result_text"]


# Parts let go over nothing: (cell, task, the part, its middle at the target, world m).
# check refuses a place with nothing under the part's centre (issue 24), so only a part
# check does not see carried reaches the twin: the blank the UR10 takes out of the vise
FALLEN = {
    "ur10_blank": ("cnc_ur10", "cnc_past_edge", "blank", (0.40, -0.63, 0.93)),
}
# ... the others are refused by check, naming the release and what is nearest
LET_GO_OVER_NOTHING = {
    "ceiling_ur5e_box": (
        "ceiling_conveyor_ur5e",
        "conveyor_pick_past_table",
        "step 9 release 'past_outfeed': the part 'box' would be let go with nothing under it",
    ),
    "ur3e_bracket": (
        "screwing_ur3e",
        "bracket_beside_bench",
        "step 8 release 'beside_bench': the part 'bracket' would be let go with nothing under it",
    ),
    "ur10e_block": (
        "guard_window_ur10e",
        "unload_press_past_table",
        "step 8 release 'past_table': the part 'block' would be let go with nothing under it",
    ),
}


@pytest.mark.parametrize("case", LET_GO_OVER_NOTHING.values(), ids=LET_GO_OVER_NOTHING.keys())
def test_check_refuses_a_part_let_go_over_nothing(case):
    cell_name, task_name, error = case
    code, out = cli("check", cell(cell_name), task(task_name))
    assert code == 1
    assert out["errors"][0].startswith(error), out["errors"]


@pytest.mark.parametrize("case", FALLEN.values(), ids=FALLEN.keys())
def test_a_failed_place_reports_the_offset_where_the_part_comes_to_rest(case):
    """Each falls 0.8-0.9 m to the floor: the offset in the result is the one at rest."""
    cell_name, task_name, part, target = case
    code, out = cli("dry-run", cell(cell_name), task(task_name))
    assert (code, out["result_code"]) == (1, 3), out["result_text"]
    at_rest_mm = 1000 * math.dist(out["parts_end_m"][part], target)
    assert at_rest_mm > 750
    assert place_failed_mm(out) == pytest.approx(at_rest_mm, abs=10), (
        out["result_text"],
        out["parts_end_m"],
    )


def test_grip_miss_on_a_tall_suction_carton_is_no_part():
    """The carton is 200 mm tall: the fault must act on the carton the cups would seal on,
    wherever its middle is; retries find nothing, the job ends with 1."""
    code, out = cli(
        "dry-run", cell("two_pallet_ur20"), task("pallet_left"), "--inject", "grip_miss@grip"
    )
    assert (code, out["result_code"]) == (1, 1), out["result_text"]


def test_check_refuses_jaws_that_open_narrower_than_the_part():
    """Jaws with a 40 mm stroke cannot straddle a 50 mm box; the same cell with 85 mm
    passes (test above)."""
    code, out = cli("check", cell("ceiling_conveyor_ur5e_narrow_jaws"), task("conveyor_pick"))
    assert (code, out["ok"]) == (1, False), out["errors"]
    assert any("box" in error for error in out["errors"]), out["errors"]


CELL_OF = {"pallet": "two_pallet_ur20", "conveyor": "ceiling_conveyor_ur5e", "peg": "peg_ur3"}

# Bad input: (file to spoil, text replaced, replacement, what the message must name).
BAD = {
    "unknown_frame": (
        "tasks/conveyor_pick.yaml",
        "  - place: {at: outfeed,",
        "  - place: {at: outfed,",
        "outfed",
    ),
    "unknown_contact_fixture": (
        "tasks/peg.yaml",
        "contact: [wall_xm, wall_xp,",
        "contact: [wall_xm, wal_xp,",
        "wal_xp",
    ),
    "angle_over_360": (
        "cells/peg_ur3.yaml",
        "hole: {xyz: [0.30, 0.15, 0.89], rpy: [180, 0, 0]}",
        "hole: {xyz: [0.30, 0.15, 0.89], rpy: [180, 0, 400]}",
        "400",
    ),
    "pattern_index_unknown": ("tasks/pallet_left.yaml", "index: slot}", "index: slto}", "slto"),
}


@pytest.mark.parametrize("case", BAD.values(), ids=BAD.keys())
def test_bad_input_is_one_located_line_and_exit_2(tmp_path, case):
    spoiled, old, new, named = case
    for sub in ("cells", "tasks"):
        (tmp_path / sub).mkdir()
        for path in (HERE / sub).glob("*.yaml"):
            (tmp_path / sub / path.name).write_text(path.read_text())
    text = (tmp_path / spoiled).read_text()
    assert old in text
    (tmp_path / spoiled).write_text(text.replace(old, new, 1))
    cell_file = next(f"cells/{name}.yaml" for key, name in CELL_OF.items() if key in spoiled)
    task_file = spoiled if spoiled.startswith("tasks/") else "tasks/peg.yaml"
    done = subprocess.run(
        [str(Path(sys.executable).with_name("cellrunner")), "check", cell_file, task_file],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if ": error: " in line]
    assert len(lines) == 1, done.stderr
    assert re.match(rf"^{re.escape(spoiled)}:\d+:\d+: error: ", lines[0]), lines[0]
    assert named in lines[0], lines[0]


def test_a_block_off_its_frame_placed_blind_is_refused():
    """SPEC 12, visual alignment: the block lies 8 mm / 6 mm / 4 deg off its frame."""
    code, out = cli("dry-run", cell("align_ur5"), task("blind_pick_ur5"))
    assert (code, out["result_code"]) == (1, 3), out["result_text"]
    assert place_failed_mm(out) >= 5.0, out["result_text"]


def test_a_block_off_its_frame_aligned_before_the_pick_is_placed():
    code, out = cli("check", cell("align_ur5"), task("align_pick_ur5"))
    assert (code, out["ok"]) == (0, True), out["errors"]
    code, out = cli("dry-run", cell("align_ur5"), task("align_pick_ur5"))
    assert (code, out["result_code"]) == (0, 0), (out["result_text"], out["errors"])
    assert math.dist(out["parts_end_m"]["block"], (0.40, 0.30, 0.825)) < 0.005


def test_an_upper_layer_slot_rehearsed_alone_is_0_on_the_earlier_slots_cartons():
    """SPEC 12: a single dry-run of a pattern slot rehearses it with the parts of the
    earlier slots already in place. Slot 7 is layer 2, row 1, column 1."""
    code, out = cli("dry-run", cell("two_pallet_ur20"), task("pallet_left"), "-p", "slot=7")
    assert (code, out["result_code"]) == (0, 0), out["result_text"]
    assert math.dist(out["parts_end_m"]["carton"], (0.205, 0.845, 0.444)) < 0.005, out[
        "parts_end_m"
    ]


def test_a_whole_pallet_rehearsed_in_one_twin_is_0_for_every_slot():
    """SPEC 12: --slots all runs the task once per value in one twin, parts staying where
    they were put; the conveyor refeeds (sim: feed). A row (JSON: a job) per slot."""
    code, out = cli("dry-run", cell("two_pallet_ur20_fed"), task("pallet_right"), "--slots", "all")
    assert code == 0, out.get("errors")
    jobs = out["jobs"]
    assert [job["params"]["slot"] for job in jobs] == list(range(8))
    assert [job["result_code"] for job in jobs] == [0] * 8, [job["result_text"] for job in jobs]


def test_check_refuses_a_carried_box_swept_through_the_box_waiting_on_the_belt():
    """The box waiting at `queue` is in the cell file: a straight line that carries the
    held box through it is refused by name, or the twin carries it past untouched."""
    code, out = cli("check", cell("ceiling_conveyor_ur5e"), task("conveyor_sweep"))
    if code == 0:
        code, out = cli("dry-run", cell("ceiling_conveyor_ur5e"), task("conveyor_sweep"))
        assert (code, out["result_code"]) == (0, 0), out["result_text"]
        assert math.dist(out["parts_end_m"]["next_box"], (0.45, 0.10, 0.925)) < 0.005, out[
            "parts_end_m"
        ]
    else:
        assert code == 1 and any("next_box" in error for error in out["errors"]), out["errors"]


def test_on_error_retreat_after_a_touch_is_accepted():
    """screw_one's on_error backs the nose out along -Z after the guarded line: from where
    the nose touched the housing, not from the line's full travel inside it."""
    code, out = cli("check", cell("screwing_ur3e"), task("screw_one"))
    assert (code, out["ok"]) == (0, True), out["errors"]


def test_a_float_param_is_proved_over_its_whole_range_or_refused():
    """A PLC may send any value in [min, max]: `clear` is 0.05-0.40 m and the UR3e cannot
    reach 0.40 m above the tray. check (default value) proves the range or refuses it."""
    code, out = cli("check", cell("screwing_ur3e"), task("bracket_clear"))
    if code == 0:
        for value in ("clear=0.05", "clear=0.40"):
            code, out = cli("check", cell("screwing_ur3e"), task("bracket_clear"), "-p", value)
            assert (code, out["ok"]) == (0, True), (value, out["errors"])
    else:
        assert code == 1 and any("clear" in error for error in out["errors"]), out["errors"]


def test_an_align_dry_run_from_a_shell_renders_without_being_told_how():
    """As a line engineer runs it: a fresh process, no MUJOCO_GL in the environment."""
    env = {key: value for key, value in os.environ.items() if key != "MUJOCO_GL"}
    done = subprocess.run(
        [
            str(Path(sys.executable).with_name("cellrunner")),
            "dry-run",
            cell("align_ur5"),
            task("align_pick_ur5"),
        ],
        capture_output=True,
        text=True,
        timeout=100,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-600:]


# Boxes shorter than the ceiling cell's 50 mm: (height, m).
SHORT = {
    "40mm": 0.04,
}


@pytest.mark.parametrize("height", SHORT.values(), ids=SHORT.keys())
def test_jaws_pick_a_short_block_resting_on_a_table(tmp_path, height):
    """The ceiling cell with a 30 or 40 mm box instead of 50 mm, each frame at the box's
    middle (resting on the belt; 3 mm above the outfeed): nothing else changes."""
    text = (HERE / "cells" / "ceiling_conveyor_ur5e.yaml").read_text()
    for old, new in [
        ("box: {size: [0.05, 0.05, 0.05]}", f"box: {{size: [0.05, 0.05, {height}]}}"),
        (
            "0.925], rpy: [180, 0, 0]}   # a box's middle",
            f"{0.9 + height / 2:.4f}], rpy: [180, 0, 0]}}   #",
        ),
        (
            "0.925], rpy: [180, 0, 0]}    # the next box",
            f"{0.9 + height / 2:.4f}], rpy: [180, 0, 0]}}    #",
        ),
        (
            "0.928], rpy: [180, 0, 90]}    # a box's middle",
            f"{0.903 + height / 2:.4f}], rpy: [180, 0, 90]}}    #",
        ),
    ]:
        assert old in text, old
        text = text.replace(old, new)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    (tmp_path / "cells" / "c.yaml").write_text(text)
    (tmp_path / "tasks" / "conveyor_pick.yaml").write_text(
        (HERE / "tasks" / "conveyor_pick.yaml").read_text()
    )
    code, out = cli(
        "check", str(tmp_path / "cells" / "c.yaml"), str(tmp_path / "tasks" / "conveyor_pick.yaml")
    )
    assert (code, out["ok"]) == (0, True), out["errors"]
