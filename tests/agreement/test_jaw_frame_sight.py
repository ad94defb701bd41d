"""A wrist camera behind the jaws' rail (issue 33): the twin draws a rail across the
fingers' tops and their stems (model.gripper.jaw_frame), which check's line of sight did
not know, and its cameras drew nothing nearer than 24 mm to the lens (MuJoCo's default
near plane, 1 % of the cell's extent): a camera 7 mm behind the rail saw the marker
through it. check now refuses it naming the rail, and the twin, with that rule switched
off, fails the align (3): it sees the rail, not the marker."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.agreement import cli
from tests.agreement.generated import copied

#: the wrist camera's place on s90344's flange, and one on the TCP's axis behind the rail
BESIDE, BEHIND = "xyz: [0.101, 0, 0.05]", "xyz: [0, 0, 0.075]"


@pytest.fixture
def behind_the_rail(tmp_path) -> tuple[str, str]:
    cell, task = copied("s90344-ur16e-aligned", tmp_path)
    text = Path(cell).read_text()
    assert BESIDE in text
    Path(cell).write_text(text.replace(BESIDE, BEHIND))
    return cell, task


def test_check_refuses_a_wrist_camera_behind_the_jaws_rail(behind_the_rail):
    code, checked = cli("check", *behind_the_rail, "--no-cache")
    assert code == 1
    (error,) = checked["errors"]
    assert "camera 'wrist' does not see marker 44: tool geometry 'rail' stands in its" in error


def test_the_twin_sees_the_rail_not_the_marker(behind_the_rail, monkeypatch):
    from cellrunner.planning import align_proof

    monkeypatch.setattr(align_proof, "_nothing_in_the_way", lambda *args: None)
    _, run = cli("dry-run", *behind_the_rail)
    assert run["result_code"] == 3, run
    assert "align: camera 'wrist' does not see marker 44" in run["result_text"]
