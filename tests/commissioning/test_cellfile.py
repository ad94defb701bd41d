"""The one cell-file writer of teach and calibrate-tcp: only the pose changes, byte for byte."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.commissioning.cellfile import CellFileError, pose_edit
from cellrunner.commissioning.teach import TeachError, frame_from_points
from tests.commissioning.conftest import CELL


@pytest.fixture
def cell(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(CELL)
    return path


def test_an_existing_flow_frame_changes_in_place(cell):
    edit = pose_edit(cell, ("frames", "drop"), [0.1, -0.2, 0.3000004], [179.99991, 0, -90])
    assert edit.after == CELL.replace(
        "drop:   {xyz: [0.7, 0.4, 0.835], rpy: [180, 0, 0]}   # keep",
        "drop:   {xyz: [0.1, -0.2, 0.3], rpy: [179.9999, 0, -90]}   # keep",
    )
    assert cell.read_text() == CELL, "nothing written before apply()"
    edit.apply()
    assert cell.read_text() == edit.after


def test_a_block_pose_keeps_its_comments_and_gains_a_missing_rpy(cell):
    text = CELL.replace(
        "  tcp: {xyz: [0, 0, 0.17]}          # nominal, from the drawing\n",
        "  tcp:   # from the drawing\n    xyz: [0, 0, 0.17]   # nominal\n",
    )
    cell.write_text(text)
    edit = pose_edit(cell, ("tool", "tcp"), [0.01, 0, 0.2], [0, 0, 90])
    assert edit.after == text.replace(
        "    xyz: [0, 0, 0.17]   # nominal\n",
        "    xyz: [0.01, 0, 0.2]   # nominal\n    rpy: [0, 0, 90]\n",
    )


def test_a_new_pose_is_the_first_entry_of_its_parent(cell):
    text = CELL.replace("  tcp: {xyz: [0, 0, 0.17]}          # nominal, from the drawing\n", "")
    cell.write_text(text)
    after = pose_edit(cell, ("tool", "tcp"), [0, 0, 0.2]).after
    assert after == text.replace("tool:\n", "tool:\n  tcp: {xyz: [0, 0, 0.2]}\n")
    assert "+  tcp: {xyz: [0, 0, 0.2]}" in pose_edit(cell, ("tool", "tcp"), [0, 0, 0.2]).diff


def test_an_inline_parent_is_refused_with_the_place(cell):
    cell.write_text(
        CELL.replace(
            "frames:\n  pick: {xyz: [0.7, -0.4, 0.83], rpy: [180, 0, 45]}   # infeed\n"
            "  drop:   {xyz: [0.7, 0.4, 0.835], rpy: [180, 0, 0]}   # keep: hand aligned\n",
            "frames: {pick: {xyz: [0.7, -0.4, 0.83]}}\n",
        )
    )
    with pytest.raises(CellFileError, match=r"c\.yaml:20:10: frames is written inline"):
        pose_edit(cell, ("frames", "new"), [0, 0, 0], [0, 0, 0])


def test_three_points_make_a_right_handed_frame():
    T = frame_from_points(
        [1, 1, 0], [1, 2, 0], [0, 1.5, 0]
    )  # X along world +Y, plane point on world -X
    assert np.allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert np.allclose(T[:3, 3], [1, 1, 0])


def test_points_on_one_line_or_too_close_are_refused():
    with pytest.raises(TeachError, match=r"the plane point lies 0\.0 deg off the X axis"):
        frame_from_points([0, 0, 0], [0.1, 0, 0], [0.3, 0, 0])
    with pytest.raises(TeachError, match=r"the \+X point is 2.0 mm from another point"):
        frame_from_points([0, 0, 0], [0.002, 0, 0], [0, 0.1, 0])
