"""The MJCF document of one cell being written: its XML root, its asset section (the
materials every body uses, the meshes by file and scale) and the contact stiffness the
physics step allows. The per-concern writers (:mod:`.mjcf_arm`, :mod:`.mjcf_bodies`,
:mod:`.mjcf_sensors`, :mod:`.cameras`, :mod:`.depth`, :mod:`.vacuum`,
:mod:`.tool_changer`, :mod:`.belts`) add to it; :mod:`.mjcf` orders them."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Mesh, Shape, Sphere
from cellrunner.planning.stl import binary_stl
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.mjcf_attrs import ShapeAttrs, fmt


class MjcfDocument:
    # set by the builder from the physics step before any body is written
    timestep_s: float
    grasp_solref: str

    def __init__(self, desc: TwinDescription) -> None:
        self.desc = desc
        self.root = ET.Element("mujoco", model=desc.name)
        self.assets: ET.Element | None = None
        self._meshes: dict[str, str] = {}
        self.mesh_files: dict[str, bytes] = {}

    # -- assets ---------------------------------------------------------------------
    def _assets(self) -> None:
        a = self.assets = ET.SubElement(self.root, "asset")
        ET.SubElement(
            a,
            "texture",
            name="grid",
            type="2d",
            builtin="checker",
            width="512",
            height="512",
            rgb1="0.80 0.80 0.78",
            rgb2="0.74 0.74 0.72",
        )
        ET.SubElement(
            a,
            "material",
            name="floor",
            texture="grid",
            texrepeat="2 2",
            texuniform="true",
            reflectance="0",
        )
        for name, rgba in (
            ("arm", "0.78 0.80 0.82 1"),
            ("joint", "0.20 0.45 0.70 1"),
            ("tool", "0.25 0.25 0.28 1"),
            ("pad", "0.10 0.10 0.10 1"),
            ("fixture", "0.62 0.52 0.40 1"),
            ("part", "0.95 0.55 0.10 1"),
        ):
            ET.SubElement(a, "material", name=name, rgba=rgba, specular="0.3")

    def _mesh_asset(self, mesh: Mesh) -> str:
        key = f"{mesh.path}|{mesh.scale}"
        if key not in self._meshes:
            name = f"mesh{len(self._meshes)}"
            assert self.assets is not None
            self.mesh_files[f"{name}.stl"] = binary_stl(mesh.path)
            ET.SubElement(
                self.assets, "mesh", name=name, file=f"{name}.stl", scale=fmt([mesh.scale] * 3)
            )
            self._meshes[key] = name
        return self._meshes[key]

    def _shape_attrs(self, shape: Shape) -> ShapeAttrs:
        if isinstance(shape, Box):
            return {"type": "box", "size": fmt(np.asarray(shape.size_m) / 2)}
        if isinstance(shape, Cylinder):
            return {"type": "cylinder", "size": fmt([shape.radius_m, shape.length_m / 2])}
        if isinstance(shape, Sphere):
            return {"type": "sphere", "size": fmt([shape.radius_m])}
        if isinstance(shape, Mesh):
            return {"type": "mesh", "mesh": self._mesh_asset(shape)}
        raise TypeError(f"unsupported shape {type(shape).__name__}")
