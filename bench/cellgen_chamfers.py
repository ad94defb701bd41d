"""Chamfered holes in generated cells (issue 33): each hole kind of
:mod:`bench.cellgen_holes` drawn again with the top inner edge of every wall bevelled.

``KIND_chamfered`` is the case of ``KIND`` on the same seed (the same arm, pin, fit and
witnesses), its four walls turned into mesh fixtures: each wall's box with the edge it
shows the hole cut at :data:`CHAMFER_ANGLE_DEG` (45 deg), 1-3 mm wide and deep
(:data:`CHAMFER_M`), written as ``meshes/WALL.stl`` beside the cell file (``mesh: {file:
...}``, SPEC section 3; a convex mesh, as check and the twin both take a mesh's convex
hull). The walls keep their names and poses and stay named in the descend's and the
insert's ``contact:``; a bevel only takes material away, so the witnesses the plain case
proved clear stay clear.

The truth is the plain kind's (see :mod:`bench.cellgen_holes`): an arm held in position
is compliant along the insert's axis only, so a chamfer guides nothing in:

- ``hole_fit_chamfered``: the centred pin slides in past the chamfers without touching
  them (feasible);
- ``jam_rim_chamfered``: the pin's tip 0.3 mm to the chamfer's width + 0.5 mm over the
  inner face of ``wall_xp`` (:data:`RIM_OVERLAP_M`): it lands on the chamfer's slope (or on
  the flat rim past it) and jams, as it does on a rim without a chamfer;
- ``hole_too_shallow_chamfered`` and ``jam_interference_chamfered``: broken as their plain
  kinds (the floor too high; 0.1 mm of interference that the chamfers lead the pin onto).
"""

from __future__ import annotations

import math
import random
import struct
from typing import Any

import numpy as np

#: each chamfered kind and the plain hole kind it is drawn as
CHAMFERED = {
    f"{kind}_chamfered": kind
    for kind in ("hole_fit", "hole_too_shallow", "jam_rim", "jam_interference")
}
CHAMFERED_FEASIBLE = ("hole_fit_chamfered",)
CHAMFERED_DEFECTS = tuple(k for k in CHAMFERED if k not in CHAMFERED_FEASIBLE)
CHAMFERED_KINDS = CHAMFERED_FEASIBLE + CHAMFERED_DEFECTS
#: the chamfer's width across the wall and depth down it (m), drawn per case
CHAMFER_M = (0.001, 0.003)
CHAMFER_ANGLE_DEG = 45.0
#: a jam_rim_chamfered case's overlap of the pin's tip over wall_xp's inner face (m): from
#: the first value to the chamfer's width plus the second (on its slope or past it, on the rim)
RIM_OVERLAP_M = (0.0003, 0.0005)
#: the direction (in the wall's own axes) from each wall to the hole it surrounds
INWARD = {"wall_xm": (1, 0), "wall_xp": (-1, 0), "wall_ym": (0, 1), "wall_yp": (0, -1)}
MESH_FOLDER = "meshes"


def generate(seed: int, kind: str) -> Any:
    """The chamfered case of ``seed`` as ``kind`` says (one of :data:`CHAMFERED_KINDS`)."""
    from bench import cellgen, cellgen_holes

    if kind not in CHAMFERED:
        raise ValueError(f"unknown chamfered kind {kind!r}; known: {', '.join(CHAMFERED)}")
    plain = cellgen_holes.generate(seed, CHAMFERED[kind])
    rng = random.Random(f"{seed}-{kind}")  # its own draws: the plain case's stay as they were
    chamfer_m = round(rng.uniform(*CHAMFER_M), 4)
    cell = {**plain.cell, "cell": f"gen-{seed}-{kind}"}
    fixtures, files = [], {}
    for fixture in plain.cell["fixtures"]:
        if fixture["name"] in INWARD:
            fixture, stl = chamfered_wall(fixture, chamfer_m)
            files[fixture["mesh"]["file"]] = stl
        fixtures.append(fixture)
    cell["fixtures"] = fixtures
    if kind == "jam_rim_chamfered":  # the tip over the chamfer of wall_xp, not in the bore
        low, past = RIM_OVERLAP_M
        overlap_m = rng.uniform(low, chamfer_m + past)
        cell["frames"] = _moved_over_rim(cell, overlap_m - cellgen_holes.RIM_OVERLAP_M)
    return cellgen.Case(seed, kind, cell, plain.task, plain.witness_deg, files=files)


def chamfered_wall(fixture: dict[str, Any], chamfer_m: float) -> tuple[dict[str, Any], bytes]:
    """The wall ``fixture`` (a box named in :data:`INWARD`) as a mesh fixture with its top
    inner edge bevelled ``chamfer_m`` wide at :data:`CHAMFER_ANGLE_DEG`, and the binary
    STL (m, the wall's own axes: the box's) of that mesh."""
    name = fixture["name"]
    path = f"{MESH_FOLDER}/{name}.stl"
    wall = {
        ("mesh" if key == "box" else key): ({"file": path} if key == "box" else value)
        for key, value in fixture.items()
    }
    vertices = bevelled_box(fixture["box"]["size"], INWARD[name], chamfer_m)
    return wall, binary_stl(hull_triangles(vertices))


def bevelled_box(size_m: list[float], inward: tuple[int, int], chamfer_m: float) -> np.ndarray:
    """The corners (m) of a box of ``size_m`` centred on its origin whose top edge on the
    side ``inward`` points to is cut ``chamfer_m`` across and ``chamfer_m`` x tan(angle)
    down: that edge's two corners become four."""
    half = np.asarray(size_m, float) / 2
    n = np.array([*inward, 0.0])
    drop_m = chamfer_m * math.tan(math.radians(CHAMFER_ANGLE_DEG))
    corners = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                p = half * (sx, sy, sz)
                if sz > 0 and float(np.dot(p, n)) > 0:  # on the edge that faces the hole
                    corners.append(p - chamfer_m * n)  # on the top, back from the edge
                    corners.append(p - (0.0, 0.0, drop_m))  # on the inner face, below it
                else:
                    corners.append(p)
    return np.array(corners)


def hull_triangles(vertices: np.ndarray) -> np.ndarray:
    """(n, 3, 3) triangles of the convex hull of ``vertices``, wound counter-clockwise
    seen from outside (outward right-handed normals), in a reproducible order."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    triangles = []
    for simplex, plane in zip(hull.simplices, hull.equations, strict=True):
        a, b, c = vertices[simplex]
        if float(np.dot(np.cross(b - a, c - a), plane[:3])) < 0:
            b, c = c, b
        triangles.append((a, b, c))
    return np.array(triangles)


def binary_stl(triangles: np.ndarray) -> bytes:
    """The binary STL of ``triangles`` ((n, 3, 3), m): an empty header, each triangle's
    unit normal and corners in single precision."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    normals = np.cross(b - a, c - a)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    out = bytearray(80) + struct.pack("<I", len(triangles))
    for normal, corners in zip(normals, triangles, strict=True):
        out += struct.pack("<12fH", *normal, *corners.reshape(-1), 0)
    return bytes(out)


def _moved_over_rim(cell: dict[str, Any], further_m: float) -> dict[str, Any]:
    """The cell's frames with ``hole`` moved ``further_m`` more towards ``wall_xp``."""
    walls = {f["name"]: f for f in cell["fixtures"]}
    centre = np.asarray(walls["hole_floor"]["pose"]["xyz"][:2], float)
    towards = np.asarray(walls["wall_xp"]["pose"]["xyz"][:2], float) - centre
    ux = towards / float(np.linalg.norm(towards))
    hole = dict(cell["frames"]["hole"])
    xyz = list(hole["xyz"])
    xyz[0] = round(xyz[0] + further_m * float(ux[0]), 5)
    xyz[1] = round(xyz[1] + further_m * float(ux[1]), 5)
    hole["xyz"] = xyz
    return {**cell["frames"], "hole": hole}
