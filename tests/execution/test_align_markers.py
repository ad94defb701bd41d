"""Markers live on what carries them (SPEC section 13) and check proves an align's camera
sees and reads its marker (issue 33): a marker named by id on its part, aligned on in
the twin; an inline marker off its part, a camera that loses the marker at a corner of
max_correction, a look too noisy for the tolerance: each one refusal of check, naming
its fix."""

from __future__ import annotations

import subprocess
import sys

from tests.conftest import ROOT
from tests.execution.align_rig import align_row, cellrunner, project
from tests.rig import ENV

#: the block (40 x 40 x 50 mm) carries marker 7 on its top face, in its own frame
BLOCK = "{name: block, box: {size: [0.04, 0.04, 0.05]}, mass: 0.2, at: infeed,"
MARKED = BLOCK + " markers: [{dictionary: DICT_4X4_50, id: 7, size: 0.03, pose: {xyz: [0, 0, Z]}}],"
INLINE = (
    "marker: {dictionary: DICT_4X4_50, id: 7, size: 0.03, "
    "pose: {xyz: [0, 0, -0.025], rpy: [180, 0, 0]}}"
)


def marked_project(tmp_path, z: str = "0.025", task_edit=None):
    """The example project with marker 7 on the block's top face (at ``z`` in the block's
    frame) and the align naming it by id."""

    def edit(t: str) -> str:
        assert INLINE in t
        t = t.replace(INLINE, "marker: 7")
        return task_edit(t) if task_edit is not None else t

    cell, task, _blind = project(tmp_path, task_edit=edit)
    text = cell.read_text()
    assert BLOCK in text
    cell.write_text(text.replace(BLOCK, MARKED.replace("Z", z)))
    return cell, task


def failures(out: dict) -> list[dict]:
    return out["failed_slots"]


def test_a_marker_named_by_id_is_printed_on_its_part_and_the_twin_aligns_on_it(tmp_path):
    cell, task = marked_project(tmp_path)
    code, out, err = cellrunner("check", str(cell), str(task), "--json")
    assert code == 0, (out.get("errors"), err[-2000:])
    code, out, err = cellrunner("dry-run", str(cell), str(task), "--json")
    assert code == 0 and out["result_code"] == 0, (out.get("errors"), err[-2000:])
    message = align_row(out)["message"]
    xyz = [float(v) for v in message.split("xyz [")[1].split("]")[0].split(",")]
    yaw = float(message.split("rpy [")[1].split("]")[0].split(",")[2])
    # the block lies 8 mm, 6 mm, 4 deg off its frame; its own marker says so
    assert abs(xyz[0] - 8.0) < 0.5 and abs(xyz[1] - 6.0) < 0.5 and abs(yaw - 4.0) < 0.3, message


def test_a_cell_marker_off_its_part_is_a_located_error(tmp_path):
    cell, task = marked_project(tmp_path, z="0.045")
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "validate", str(cell), str(task)],
        capture_output=True, text=True, cwd=ROOT, env=ENV, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    line = next(x for x in r.stderr.splitlines() if "off the surface" in x)
    assert line.startswith(f"{cell}:") and ": error: " in line, line
    assert (
        "marker 7 is off the surface of part 'block': its centre is 20.0 mm above the top face"
        in line
    )
    assert "Traceback" not in r.stderr


def test_an_unknown_marker_id_is_a_located_error(tmp_path):
    cell, task = marked_project(tmp_path, task_edit=lambda t: t.replace("marker: 7", "marker: 9"))
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", "validate", str(cell), str(task)],
        capture_output=True, text=True, cwd=ROOT, env=ENV, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2
    line = next(x for x in r.stderr.splitlines() if "marker 9" in x)
    assert line.startswith(f"{task}:") and "markers there and on the fixtures: 7" in line, line


def test_an_inline_marker_20_mm_above_its_part_is_refused(tmp_path):
    cell, task, _ = project(
        tmp_path, task_edit=lambda t: t.replace("xyz: [0, 0, -0.025]", "xyz: [0, 0, -0.045]")
    )
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 1
    text = " ".join(out["errors"])
    assert (
        "marker 7 is off the surface of part 'block': its centre is 20.0 mm above the top face"
        in text
    ), text
    assert {f["kind"] for f in failures(out)} <= {"marker"}


def test_a_camera_that_loses_the_marker_at_a_corner_of_max_correction_is_refused_once(tmp_path):
    cell, task, _ = project(
        tmp_path,
        task_edit=lambda t: t.replace("xyz: [0.015, 0.015, 0]", "xyz: [0.25, 0.015, 0]"),
    )
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 1
    lines = [e for e in out["errors"] if "does not see all of marker 7" in e]
    assert len(lines) == 1, out["errors"]  # one error for the cause, not one per correction
    assert "for 8 of the 9 corrections max_correction allows" in lines[0], lines[0]
    assert "fix: a look farther from the marker (standoff)" in lines[0]


def test_a_look_too_noisy_for_the_tolerance_is_refused_with_its_fixes(tmp_path):
    # an 8 mm marker from 300 mm spans 16 px: its turn reads to 1.3 deg (2 std)
    cell, task, _ = project(
        tmp_path,
        task_edit=lambda t: t.replace("size: 0.03,", "size: 0.008,").replace(
            "attempts: 3", "attempts: 3\n      standoff: 0.3"
        ),
    )
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 1
    lines = [e for e in out["errors"] if "one look of camera 'wrist' at marker 7" in e]
    assert len(lines) == 1, out["errors"]
    assert "(8 mm, 16 px wide from 300 mm) reads its x, y, rz within" in lines[0], lines[0]
    assert (
        "fix: a bigger marker (at least" in lines[0]
        and "a closer look (standoff at most" in lines[0]
    )


def test_reading_the_full_pose_of_a_small_marker_is_refused_and_fewer_axes_suggested(tmp_path):
    # z in max_correction: the full pose is read, its tilts far less sure than x, y, rz
    cell, task, _ = project(
        tmp_path,
        task_edit=lambda t: t.replace("xyz: [0.015, 0.015, 0]", "xyz: [0.015, 0.015, 0.002]"),
    )
    code, out, _ = cellrunner("check", str(cell), str(task), "--json")
    assert code == 1
    lines = [e for e in out["errors"] if "one look of camera 'wrist'" in e]
    assert len(lines) == 1, out["errors"]
    assert "reads its x, y, z, rx, ry, rz within" in lines[0]
    assert "fewer axes (max_correction z, rx and ry 0" in lines[0], lines[0]
