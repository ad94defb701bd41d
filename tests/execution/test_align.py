"""The align step end to end in the MuJoCo twin (dry-run): the block lies off its frame,
the wrist camera sees the marker printed on it, the arm corrects and places it; check
proves the max_correction box; bad align steps are located input errors."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT
from tests.execution.align_rig import align_row, cellrunner, project
from tests.rig import ENV

#: a loopback address of this process's own: several checkouts run these tests at once
HOST = f"127.26.{os.getpid() % 250 + 1}.2"


def test_aligned_the_block_off_its_frame_is_placed_blind_it_is_refused(tmp_path):
    cell, task, blind = project(tmp_path)
    code, out, err = cellrunner("dry-run", str(cell), str(task), "--json")
    assert code == 0 and out["result_code"] == 0, (out.get("errors"), err[-2000:])
    message = align_row(out)["message"]
    # the correction found is the block's offset: 8 mm, 6 mm, 4 deg
    xyz = [float(v) for v in message.split("xyz [")[1].split("]")[0].split(",")]
    yaw = float(message.split("rpy [")[1].split("]")[0].split(",")[2])
    assert abs(xyz[0] - 8.0) < 0.5 and abs(xyz[1] - 6.0) < 0.5 and abs(yaw - 4.0) < 0.3, message
    code, out, _ = cellrunner("dry-run", str(cell), str(blind), "--json")
    assert code == 1 and out["result_code"] == 3, out.get("errors")
    assert "place failed: part 'block'" in " ".join(out["errors"])


def test_a_part_beyond_max_correction_fails_the_align_with_3(tmp_path):
    cell, task, _ = project(tmp_path, offset="{xyz: [0.022, 0.0, 0], rpy: [0, 0, 0]}")
    code, out, _ = cellrunner("dry-run", str(cell), str(task), "--json")
    assert code == 1 and out["result_code"] == 3
    row = align_row(out)
    assert row["status"] == "failed"
    assert "lies beyond max_correction (x +" in row["message"], row["message"]
    x_mm = float(row["message"].split("(x +")[1].split(" mm")[0])
    assert abs(x_mm - 22.0) < 1.0, "the first look finds the block 22 mm off"
    assert not any(s["kind"] == "descend" and s["status"] == "ok" for s in out["steps"])


def test_check_proves_every_corner_of_the_correction_box(tmp_path):
    cell, task, _ = project(tmp_path)
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 0, out["errors"]
    assert len(out["slots_checked"]["align:infeed"]) == 9  # centre + 2 x 2 x 2 corners
    # a box that reaches under the table cannot be proved: check names the corner (a
    # box with z reads the marker's full pose: a tolerance that its noise can meet)
    cell, task, _ = project(
        tmp_path / "deep",
        task_edit=lambda t: t.replace(
            "xyz: [0.015, 0.015, 0]", "xyz: [0.015, 0.015, 0.06]"
        ).replace("tolerance: {xyz: 0.001, rpy: 0.5}", "tolerance: {xyz: 0.01, rpy: 16}"),
    )
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 1
    assert any(e.startswith("align:infeed=") for e in out["errors"]), out["errors"]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda t: t.replace("camera: wrist", "camera: wirst"),
            "unknown camera 'wirst'",
        ),
        (
            lambda t: t.split("  - pick:")[0] + "  - move: home\n",
            "align must come before a step aimed at a frame",
        ),
    ],
)
def test_bad_align_steps_are_located_input_errors(tmp_path, edit, message):
    cell, task, _ = project(tmp_path, task_edit=edit)
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "validate", str(cell), str(task)],
        capture_output=True, text=True, cwd=ROOT, env=ENV, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2
    line = next(x for x in r.stderr.splitlines() if message in x)
    assert line.startswith(f"{task}:") and ": error: " in line, line


def test_on_the_arm_align_sees_through_the_image_source(tmp_path):
    """`run --backend ur` against `cellrunner twin`: the unmodified ur_rtde client moves
    the arm, the pictures come from the twin's camera server (the default image source)."""
    from tests.twin.cell_rig import twin

    cell, task, _ = project(tmp_path)
    with twin(cell, HOST):
        code, out, err = cellrunner(
            "run", str(cell), str(task), "--backend", "ur", "--robot-host", HOST,
            "--image-source", "twin", "--json",
        )  # fmt: skip
    assert code == 0 and out["result_code"] == 0, (out.get("errors"), err[-2000:])
    assert "in 2 looks" in align_row(out)["message"]
