"""What the cell file explains, never an obstacle (SPEC section 12): the arm in its
measured configuration, the tool, a held part, the fixtures and the parts, each grown by
the zone's padding.

The robot's solids move with its joints (:meth:`KnownScene.robot_at`); the fixtures and
parts stand still and are marked once in the map's table of known voxels
(:meth:`KnownScene.static_solids`, meshes by their surfaces: a fence's hull would hide
the whole cell). Parts the arm set down are added as it releases them (:meth:`set_down`).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.geometry import Mesh, Placed, invert
from cellrunner.perception.solids import PlacedSolid, Solid, hull_of, solid_of

if TYPE_CHECKING:
    from cellrunner.planning.world import CellWorld


@functools.cache
def arm_solids(model: str) -> tuple[PlacedSolid, ...]:
    """The arm's convex parts as solids on their links (each in its joint's frame): the
    hulls of their vertices, as the twin draws them."""
    from cellrunner.model.arm_geometry import arm_geometry

    return tuple(
        PlacedSolid(p.link, hull_of(p.vertices_m), p.body, np.eye(4))
        for p in arm_geometry(model).parts
    )


class KnownScene:
    """The known solids of one cell (see the module docstring); built from its planning
    world."""

    def __init__(self, world: CellWorld) -> None:
        self.world = world
        kin = world.kinematics
        self.T_world_base = kin.T_world_base
        q0 = world.q_home_rad
        frames = world.collision.joint_frames(q0[None])[0]
        T_joint6_flange = invert(frames[6]) @ kin.T_world_flange(q0)
        self.T_joint6_tcp = T_joint6_flange @ kin.T_flange_tcp
        tool = [
            PlacedSolid(
                f"tool {t.name!r}", solid_of(t.shape), 6, T_joint6_flange @ t.T_parent_shape
            )
            for t in world.tool
        ]
        self.robot: tuple[PlacedSolid, ...] = (*arm_solids(world.spec.arm), *tool)
        self.fixtures: tuple[Placed, ...] = tuple(world.fixtures)
        self.parts: list[Placed] = [
            p for p in (self._spawned(part.name, part.at) for part in world.loaded.cell.parts) if p
        ]
        self._held: dict[str, PlacedSolid] = {}

    def _spawned(self, name: str, frame: str) -> Placed | None:
        from cellrunner.model.expand import frame_pose

        T_world_frame = frame_pose(self.world.loaded.cell, frame)
        placed = self.world.part_at(frame, T_world_frame)
        if placed is None:
            return None
        return Placed(f"part {name!r}", placed.shape, T_world_frame @ placed.T_parent_shape)

    def held(self, part: Placed | None) -> PlacedSolid | None:
        """A carried part (placed in the TCP frame) as a solid on the flange's body."""
        if part is None:
            return None
        cached = self._held.get(part.name)
        if cached is None or not np.array_equal(
            cached.T_body_solid, self.T_joint6_tcp @ part.T_parent_shape
        ):
            cached = PlacedSolid(
                f"part {part.name!r}",
                solid_of(part.shape),
                6,
                self.T_joint6_tcp @ part.T_parent_shape,
            )
            self._held[part.name] = cached
        return cached

    def robot_at(
        self, q_rad: np.ndarray, held: Placed | None = None
    ) -> list[tuple[Solid, np.ndarray]]:
        """The arm's, tool's and held part's solids with their world poses at ``q_rad``."""
        frames = self.world.collision.joint_frames(np.asarray(q_rad, float)[None])[0]
        return self.robot_at_frames(frames, held)

    def robot_at_frames(
        self, frames: np.ndarray, held: Placed | None = None
    ) -> list[tuple[Solid, np.ndarray]]:
        """:meth:`robot_at` from joint frames already computed ((7, 4, 4), world)."""
        solids = list(self.robot)
        carried = self.held(held)
        if carried is not None:
            solids.append(carried)
        out = []
        for s in solids:
            T_world_body = self.T_world_base if s.body == 0 else frames[s.body]
            out.append((s.solid, T_world_body @ s.T_body_solid))
        return out

    def set_down(self, part: Placed, T_world_tcp: np.ndarray) -> None:
        """A part the arm released at ``T_world_tcp`` (placed in the TCP frame) now stands
        there: known from now on."""
        self.parts.append(Placed(part.name, part.shape, T_world_tcp @ part.T_parent_shape))

    def static_solids(self) -> list[tuple[Solid, np.ndarray]]:
        """The fixtures' and parts' solids in the world, meshes left out (see
        :meth:`static_surfaces`)."""
        return [
            (solid_of(p.shape), np.asarray(p.T_parent_shape, float))
            for p in (*self.fixtures, *self.parts)
            if not isinstance(p.shape, Mesh)
        ]

    def static_surfaces(self, spacing_m: float) -> np.ndarray:
        """Points on the surfaces of the mesh fixtures (world, N x 3), no farther apart than
        ``spacing_m``."""
        from cellrunner.planning.stl import read_stl

        chunks = [np.zeros((0, 3))]
        for p in self.fixtures:
            if not isinstance(p.shape, Mesh):
                continue
            vertices, triangles = read_stl(p.shape.path)
            v = np.asarray(vertices, float) * p.shape.scale
            T = np.asarray(p.T_parent_shape, float)
            for tri in v[np.asarray(triangles)]:
                chunks.append(_sample_triangle(tri, spacing_m) @ T[:3, :3].T + T[:3, 3])
        return np.vstack(chunks)


def _sample_triangle(tri: np.ndarray, spacing_m: float) -> np.ndarray:
    """Points covering a triangle (3 x 3) on a barycentric grid of about ``spacing_m``."""
    edge = max(float(np.linalg.norm(tri[1] - tri[0])), float(np.linalg.norm(tri[2] - tri[0])), 1e-9)
    n = max(1, int(np.ceil(edge / spacing_m)))
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    keep = i + j <= n
    a, b = i[keep] / n, j[keep] / n
    return np.asarray(tri[0] + a[:, None] * (tri[1] - tri[0]) + b[:, None] * (tri[2] - tri[0]))
