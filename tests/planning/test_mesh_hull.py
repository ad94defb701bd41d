"""Convex mesh fixtures (planning/mesh_hull.py): check takes a mesh that fills its hull as
that hull, as the twin collides it, so an overlap with it is a depth (a pin pressed into
a chamfered wall) and a wall named in ``contact:`` may be pressed into by the allowance,
where a triangle surface made coal refuse the negative margin (an internal error)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from bench.cellgen_chamfers import bevelled_box, binary_stl, hull_triangles
from cellrunner.model.geometry import Box, Mesh, Placed, pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.collision import CollisionModel, ContactAllowance
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.mesh_hull import convexity
from cellrunner.planning.stl import stl_triangles
from cellrunner.sim.mesh_pieces import is_convex

HOME = np.radians([0, -90, 90, -90, -90, 0])
TOOL = (Placed("gripper", Box((0.05, 0.05, 0.1)), pose_matrix((0, 0, 0.05))),)


def _box_triangles(lo: tuple[float, ...], hi: tuple[float, ...]) -> np.ndarray:
    corners = np.array(list(itertools.product(*zip(lo, hi, strict=True))), float)
    return hull_triangles(corners)


def _write(path: Path, triangles: np.ndarray) -> Path:
    path.write_bytes(binary_stl(triangles))
    return path


def test_convexity_of_a_box_a_bevelled_wall_an_l_and_a_flat_square(tmp_path):
    box = _box_triangles((0, 0, 0), (0.2, 0.1, 0.05))
    wall = hull_triangles(bevelled_box([0.02, 0.05, 0.04], (-1, 0), 0.002))
    ell = np.concatenate(
        [
            _box_triangles((0, 0, 0), (0.2, 0.05, 0.05)),
            _box_triangles((0, 0.05, 0), (0.05, 0.2, 0.05)),
        ]
    )
    square = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    assert convexity(box) is True
    assert convexity(wall) is True
    assert convexity(ell) is False  # its hull is 1.6 times its volume
    assert convexity(square) is None
    # the twin decides alike: hulls for the convex ones, surfaces for the L, and a flat
    # mesh is left to its flat-mesh rule
    assert [is_convex(t) for t in (box, wall, ell, square)] == [True, True, False, True]
    # the file as written and read back (single precision) is still convex
    assert convexity(stl_triangles(_write(tmp_path / "wall.stl", wall))) is True


def _kin() -> ArmKinematics:
    return ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_matrix((0, 0, 0.15)))


def _tool_bottom(kin: ArmKinematics) -> np.ndarray:
    """The centre of the tool's lowest face at HOME (the box's end, 50 mm above the TCP)."""
    point = kin.T_world_tcp(HOME) @ np.array([0.0, 0.0, -0.05, 1.0])
    assert kin.T_world_tcp(HOME)[2, 2] == pytest.approx(-1.0)  # the tool points down
    return point[:3]


@pytest.mark.parametrize("into_m", [-0.002, 0.0005, 0.003])
def test_a_convex_mesh_measures_an_overlap_as_the_box_it_is(tmp_path, into_m):
    """A box written as an STL and the same box measure the same signed distance to the
    tool, inside as outside (a triangle surface read 0 or more inside)."""
    kin = _kin()
    x, y, z = _tool_bottom(kin)
    # a block whose top is into_m above the tool's lowest face
    size = (0.2, 0.2, 0.1)
    pose = pose_matrix((x, y, z + into_m - size[2] / 2))
    stl = _write(
        tmp_path / "block.stl",
        _box_triangles(tuple(-s / 2 for s in size), tuple(s / 2 for s in size)),
    )
    as_mesh = CollisionModel(kin, TOOL, [Placed("block", Mesh(stl), pose)])
    as_box = CollisionModel(kin, TOOL, [Placed("block", Box(size), pose)])
    d_mesh = as_mesh.clearance(HOME)
    d_box = as_box.clearance(HOME)
    assert (d_mesh.a, d_mesh.b.name) == (d_box.a, "block")
    assert d_mesh.distance_m == pytest.approx(-into_m, abs=1e-6)
    assert d_box.distance_m == pytest.approx(-into_m, abs=1e-6)


def test_a_convex_mesh_named_in_a_contact_allowance_is_checked(tmp_path):
    """The tool 0.5 mm into a bevelled wall allowed 1 mm: valid; 1.5 mm: a collision that
    says how far it presses in (check ended in an internal error on both)."""
    kin = _kin()
    x, y, z = _tool_bottom(kin)
    stl = _write(
        tmp_path / "wall.stl", hull_triangles(bevelled_box([0.2, 0.2, 0.04], (1, 0), 0.002))
    )
    verdicts = []
    for into_m in (0.0005, 0.0015):
        pose = pose_matrix((x, y, z + into_m - 0.02))  # its top into_m over the tool's end
        model = CollisionModel(kin, TOOL, [Placed("wall", Mesh(stl), pose)]).allowing(
            ContactAllowance("wall", "tool", -0.001)
        )
        clearance = model.clearance(HOME)
        assert clearance.distance_m == pytest.approx(-into_m, abs=1e-6)
        verdicts.append((model.is_valid(HOME), clearance.describe()))
    assert verdicts[0][0] is True
    assert verdicts[1] == (
        False,
        "tool 'gripper' presses 1.5 mm into fixture 'wall', 0.5 mm more than the 1.0 mm it may",
    )


def test_a_non_convex_mesh_in_a_contact_allowance_may_be_touched_not_entered(tmp_path):
    """An L (two blocks in one STL) does not fill its hull: coal keeps it a triangle
    surface, measures no depth into it and refused the allowance's negative margin (check
    ended in an internal error). Such a pair may touch, never overlap: the tool 0.5 mm
    above it is valid, 0.5 mm into it is not, whatever the allowance."""
    kin = _kin()
    x, y, z = _tool_bottom(kin)
    ell = np.concatenate(
        [
            _box_triangles((-0.1, -0.1, -0.04), (0.1, 0.1, 0.0)),
            _box_triangles((-0.1, 0.05, 0.0), (-0.05, 0.1, 0.05)),
        ]
    )
    stl = _write(tmp_path / "ell.stl", ell)
    assert convexity(ell) is False
    verdicts = []
    for into_m in (-0.0005, 0.0005):
        pose = pose_matrix((x, y, z + into_m))  # its lower block's top into_m over the tool
        model = CollisionModel(kin, TOOL, [Placed("ell", Mesh(stl), pose)]).allowing(
            ContactAllowance("ell", "tool", -0.001)
        )
        verdicts.append(model.is_valid(HOME))
    assert verdicts == [True, False]
