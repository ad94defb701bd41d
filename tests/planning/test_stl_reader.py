"""The one STL reader: binary and ASCII files give the same triangles, MuJoCo gets binary
bytes of either, and a file that is not STL is named in the error."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.planning.stl import binary_stl, read_stl, stl_triangles

CORNERS = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [0, 1, 0], [0, 0, 1]]], float)


def _ascii(corners: np.ndarray) -> str:
    facets = "".join(
        "facet normal 0 0 0\n outer loop\n"
        + "".join(f"  vertex {x} {y} {z}\n" for x, y, z in tri)
        + " endloop\nendfacet\n"
        for tri in corners
    )
    return f"solid t\n{facets}endsolid t\n"


def test_ascii_and_binary_stl_read_alike(tmp_path):
    ascii_path = tmp_path / "a.stl"
    ascii_path.write_text(_ascii(CORNERS))
    binary_path = tmp_path / "b.stl"
    binary_path.write_bytes(binary_stl(ascii_path))
    assert binary_stl(binary_path) == binary_path.read_bytes()  # binary passes as it is
    np.testing.assert_array_equal(stl_triangles(ascii_path), CORNERS)
    np.testing.assert_array_equal(stl_triangles(binary_path), CORNERS)
    for path in (ascii_path, binary_path):
        vertices, triangles = read_stl(path)
        assert vertices.shape == (4, 3) and triangles.shape == (2, 3)
        np.testing.assert_array_equal(vertices[triangles], CORNERS)


def test_a_file_that_is_not_stl_is_named(tmp_path):
    path = tmp_path / "notes.stl"
    path.write_text("hello")
    with pytest.raises(ValueError, match=r"notes\.stl is neither a binary nor an ASCII STL"):
        read_stl(path)
    with pytest.raises(ValueError, match=r"cannot read mesh .*missing\.stl"):
        binary_stl(tmp_path / "missing.stl")
