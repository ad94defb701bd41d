"""Markers live on what carries them (SPEC section 13): the surface rule, an id resolved
in the align's target frame, and the twin printing the cell file's markers only."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.model.geometry import Box, Cylinder, Sphere, pose_matrix
from cellrunner.model.marker_surface import off_surface
from tests.conftest import ROOT

BOX = Box((0.04, 0.04, 0.05))


@pytest.mark.parametrize(
    ("shape", "xyz", "rpy"),
    [
        (BOX, (0, 0, 0.025), (0, 0, 0)),  # top face
        (BOX, (0.005, -0.005, -0.025), (180, 0, 30)),  # bottom face, turned in it
        (BOX, (0.02, 0, 0), (0, 90, 0)),  # +x face: Z along +x
        (Cylinder(0.03, 0.1), (0, 0, 0.05), (0, 0, 45)),  # end cap
        (Cylinder(0.03, 0.1), (0, 0.03, 0.01), (-90, 0, 0)),  # side, Z out along +y
        (Sphere(0.05), (0, 0, 0.05), (0, 0, 0)),
    ],
)
def test_a_marker_on_a_face_is_on_the_surface(shape, xyz, rpy):
    assert off_surface(shape, pose_matrix(xyz, rpy), 0.02) is None


@pytest.mark.parametrize(
    ("xyz", "rpy", "size", "problem"),
    [
        ((0, 0, 0.045), (0, 0, 0), 0.02, "its centre is 20.0 mm above the top face"),
        ((0, 0, 0.015), (0, 0, 0), 0.02, "its centre is 10.0 mm inside the top face"),
        ((0, 0, 0.025), (180, 0, 0), 0.02, "its Z (out of the printed face) is 180 deg from"),
        ((0.015, 0, 0.025), (0, 0, 0), 0.02, "its square reaches 5.0 mm past the edge of the top face"),
        ((0, 0, 0.025), (0, 0, 45), 0.04, "past the edge of the top face"),
    ],
)  # fmt: skip
def test_a_marker_off_its_face_says_how(xyz, rpy, size, problem):
    found = off_surface(BOX, pose_matrix(xyz, rpy), size)
    assert found is not None and problem in found, found


def test_a_marker_named_by_id_is_given_in_the_target_frame_and_printed_where_the_cell_puts_it(
    tmp_path,
):
    from cellrunner.model.load import load_cell
    from cellrunner.model.marker_place import marker_in_frame
    from cellrunner.sim.from_cell import description_of

    text = (ROOT / "cells" / "align_pick_ur10e.yaml").read_text()
    block = "{name: block, box: {size: [0.04, 0.04, 0.05]}, mass: 0.2, at: infeed,"
    table = "{name: table, box: {size: [1.0, 1.4, 0.05]}, pose: {xyz: [0.7, 0, 0.775]}}"
    assert block in text and table in text
    text = text.replace(
        block, block + " markers: [{id: 7, size: 0.03, pose: {xyz: [0, 0, 0.025]}}],"
    ).replace(
        table,
        table[:-1] + ", markers: [{id: 3, size: 0.04, pose: {xyz: [0.3, 0.5, 0.025]}}]}",
    )
    (tmp_path / "c.yaml").write_text(
        text.replace("tasks: {1: tasks/align_pick.yaml, 2: tasks/align_pick_blind.yaml}", "")
    )
    loaded = load_cell(tmp_path / "c.yaml")
    marker = marker_in_frame(loaded.cell, "infeed", 7)
    # the infeed frame points its Z down into the block: the top face is 25 mm up, -Z
    assert np.allclose(marker.pose.matrix()[:3, 3], [0, 0, -0.025], atol=1e-9)
    assert np.allclose(marker.pose.matrix()[:3, 2], [0, 0, -1], atol=1e-9)
    on_table = marker_in_frame(loaded.cell, "infeed", 3)  # not on the block: the fixture's
    world = np.array([0.7 + 0.3, 0.5, 0.775 + 0.025])
    frame = np.asarray(loaded.cell.frames["infeed"].matrix())
    assert np.allclose(frame @ [*on_table.pose.xyz, 1], [*world, 1], atol=1e-9)
    printed = {(m.part, m.key): m.T_part_marker for m in description_of(loaded).markers}
    assert set(printed) == {("block", "block-7"), ("", "fixture-3")}
    assert np.allclose(printed[("", "fixture-3")][:3, 3], world + [0, 0, 0.0003], atol=1e-9)
