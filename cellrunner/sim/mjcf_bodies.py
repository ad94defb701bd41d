"""The cell's fixtures (static geoms) and parts (free bodies) in its MJCF."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import numpy as np

from cellrunner.model.geometry import Box, Mesh, Placed
from cellrunner.planning.stl import stl_triangles
from cellrunner.sim.mjcf_attrs import PART_HITS, PARTS, fixture_bits, fmt, pose_attrs
from cellrunner.sim.mjcf_document import MjcfDocument
from cellrunner.sim.rigid_contacts import rigid_contact_attrs

#: a mesh thinner than this along some axis is treated as flat (m), and given this thickness
FLAT_MESH_M = 0.001


def _flat_mesh_box(mesh: Mesh) -> tuple[np.ndarray, np.ndarray] | None:
    """(centre, full size) of a mesh's bounding box when the mesh is flat (coplanar
    vertices along a frame axis), else None."""
    vertices = stl_triangles(mesh.path).reshape(-1, 3) * mesh.scale
    if not len(vertices):
        return None
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    size = hi - lo
    if size.min() >= FLAT_MESH_M:
        return None
    return (lo + hi) / 2, np.maximum(size, FLAT_MESH_M)


def add_fixture(builder: MjcfDocument, parent: ET.Element, placed: Placed) -> None:
    shape, T = placed.shape, placed.T_parent_shape
    if isinstance(shape, Mesh) and _add_mesh_pieces(builder, parent, placed):
        return
    flat = _flat_mesh_box(shape) if isinstance(shape, Mesh) else None
    if flat is not None:  # MuJoCo cannot hull a flat mesh: a thin box over its bounds
        center, size = flat
        T = T.copy()
        T[:3, 3] = T[:3, :3] @ center + T[:3, 3]
        shape = Box(tuple(size))
    geom = ET.SubElement(
        parent,
        "geom",
        name=f"fixture:{placed.name}",
        material="fixture",
        **fixture_bits(placed.name in builder.desc.press_fixtures),
        **builder._shape_attrs(shape),
        **pose_attrs(T),
    )
    if placed.name in builder.desc.rigid_fixtures:  # a hole's walls (issue 33)
        for key, value in rigid_contact_attrs(builder.timestep_s).items():
            geom.set(key, value)


def _add_mesh_pieces(builder: MjcfDocument, parent: ET.Element, placed: Placed) -> bool:
    """A non-convex mesh fixture as one thin prism per triangle (see :mod:`.mesh_pieces`);
    False when the mesh is convex (or too big), to be built as usual."""
    from cellrunner.sim import mesh_pieces

    mesh = placed.shape
    assert isinstance(mesh, Mesh)  # called for mesh fixtures
    triangles = stl_triangles(mesh.path) * mesh.scale
    if len(triangles) > mesh_pieces.MAX_TRIANGLES or mesh_pieces.is_convex(triangles):
        return False
    assert builder.assets is not None
    for k, vertices in enumerate(mesh_pieces.prisms(triangles)):
        name = f"{placed.name}_piece{k}"
        ET.SubElement(builder.assets, "mesh", name=name, vertex=fmt(vertices))
        ET.SubElement(
            parent,
            "geom",
            name=f"fixture:{placed.name}:{k}",
            material="fixture",
            type="mesh",
            mesh=name,
            **fixture_bits(placed.name in builder.desc.press_fixtures),
            **pose_attrs(placed.T_parent_shape),
        )
    return True


def add_part(builder: MjcfDocument, world: ET.Element, part: Any) -> None:
    feed = builder.desc.feed
    # a copy waiting to be fed (sim.feed) floats, touching nothing, until it is fed
    parked = feed is not None and part.name in feed.copies
    body = ET.SubElement(world, "body", name=f"part:{part.name}", **pose_attrs(part.T_world_part))
    if parked:
        body.set("gravcomp", "1")
    ET.SubElement(body, "freejoint", name=f"part:{part.name}")
    ET.SubElement(
        body,
        "geom",
        name=f"part:{part.name}",
        material="part",
        mass=f"{part.mass_kg:.6g}",
        friction=f"{part.friction:g} 0.01 0.0001",
        condim="4",
        solref=builder.grasp_solref,
        contype="0" if parked else str(PARTS),
        conaffinity="0" if parked else str(PART_HITS),
        **builder._shape_attrs(part.shape),
    )
