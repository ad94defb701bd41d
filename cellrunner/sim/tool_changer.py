"""A tool changer in the twin: tools parked in their rack places, one mounted on the
flange, swapped by the changer's lock output as on the line.

Rules (a changer with the usual interlock):
- the lock opens only in the rack: with the lock output off and the TCP within
  ``RACK_TOLERANCE_M`` of the mounted tool's rack pose, the tool is parked there;
  elsewhere it stays mounted (so the output being off at power-up drops nothing);
- with the lock output on and nothing mounted, the tool whose rack pose the flange stands
  at (within ``RACK_TOLERANCE_M``, with that tool's TCP) is mounted; none: nothing happens;
- ``locked`` reads true while a tool is mounted.

Mounting a tool switches, in the compiled model: the TCP site, the tool's collision
geometry (each tool's shapes are geoms of the tool body, enabled only while mounted;
the parked ones are drawn in the rack), the payload mass at the flange, and which gripper
mechanism (jaws or cups) is live.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.sim.mjcf_attrs import PADS, PARTS, STATIC, TOOL, pose_attrs, quat_of
from cellrunner.sim.wrist import GRAVITY_MPS2

if TYPE_CHECKING:
    from cellrunner.model.geometry import Placed

#: the flange must stand this close to a rack place to park or take a tool (m)
RACK_TOLERANCE_M = 0.005


@dataclass(frozen=True)
class ChangerTool:
    """One tool of a changer: TCP and shapes in the flange frame, payload, its gripper's
    kind (``jaws``, ``vacuum`` or None) and the TCP pose of the tool parked in the rack."""

    name: str
    T_flange_tcp: np.ndarray
    geometry: tuple[Placed, ...]
    payload_mass_kg: float
    payload_cog_m: tuple[float, float, float]
    gripper: str | None
    T_world_rack_tcp: np.ndarray
    jaws: Any = None  # its GripperDescription when it has jaws (the twin's one pair of jaws takes its place)


@dataclass(frozen=True)
class ToolChangerDescription:
    lock_output: str
    locked_input: str | None
    tools: tuple[ChangerTool, ...]
    mounted: str


def add_tools(
    builder: Any,
    tool_body: ET.Element,
    world_body: ET.Element,
    changer: ToolChangerDescription,
    tool_kind: int,
    static_kind: int,
) -> None:
    """Each tool's shapes on the tool body (only the mounted one collides and shows) and,
    drawn only, in its rack place (MJCF)."""

    for tool in changer.tools:
        mounted = tool.name == changer.mounted
        T_world_flange = tool.T_world_rack_tcp @ np.linalg.inv(tool.T_flange_tcp)
        for k, placed in enumerate(tool.geometry):
            ET.SubElement(
                tool_body,
                "geom",
                name=f"tool@{tool.name}:{k}",
                material="tool",
                density="0",
                contype=str(tool_kind if mounted else 0),
                conaffinity=str(static_kind if mounted else 0),
                rgba="0.25 0.25 0.28 1" if mounted else "0.25 0.25 0.28 0",
                **builder._shape_attrs(placed.shape),
                **pose_attrs(placed.T_parent_shape),
            )
            ET.SubElement(
                world_body,
                "geom",
                name=f"rack@{tool.name}:{k}",
                material="tool",
                contype="0",
                conaffinity="0",
                group="1",
                rgba="0.25 0.25 0.28 0" if mounted else "0.25 0.25 0.28 1",
                **builder._shape_attrs(placed.shape),
                **pose_attrs(T_world_flange @ placed.T_parent_shape),
            )


class ToolChanger:
    """The changer of one built SimWorld."""

    def __init__(self, world: Any, desc: ToolChangerDescription) -> None:
        self.world, self.desc = world, desc
        m = world.model
        self.tools = {t.name: t for t in desc.tools}
        self.geoms = {
            t.name: [m.geom(f"tool@{t.name}:{k}").id for k in range(len(t.geometry))]
            for t in desc.tools
        }
        self.rack_geoms = {
            t.name: [m.geom(f"rack@{t.name}:{k}").id for k in range(len(t.geometry))]
            for t in desc.tools
        }

        self.tool_kind = (TOOL, STATIC)
        self.pad_kind = (PADS, STATIC | PARTS)
        self.mounted: str | None = None
        self._mount(desc.mounted)

    @property
    def locked(self) -> bool:
        return self.mounted is not None

    @property
    def steady(self) -> bool:
        """Whether the next period mounts or parks nothing: the lock output on with a tool
        mounted, off with none, or off with the tool mounted away from its rack place
        (then it parks only where :meth:`parks_at` says)."""
        if self.locked == bool(self.world.outputs.get(self.desc.lock_output)):
            return True
        return self.mounted is not None and not self._at_rack(self.tools[self.mounted])

    def parks_at(self, tcp_xyz: np.ndarray) -> np.ndarray:
        """Per row of world TCP positions (the mounted tool's, n x 3): whether the period
        after one ending there may park the tool (lock output off, at its rack place with
        a micrometre to spare for rounding)."""
        if self.mounted is None or self.world.outputs.get(self.desc.lock_output):
            return np.zeros(len(tcp_xyz), dtype=bool)
        return _near_rack(self.tools[self.mounted], tcp_xyz, RACK_TOLERANCE_M + 1e-6)

    def drive(self) -> None:
        """Follow the lock output (before the physics step)."""
        lock_on = bool(self.world.outputs.get(self.desc.lock_output))
        if self.mounted is not None and not lock_on:
            if self._at_rack(self.tools[self.mounted]):
                self._park()
        elif self.mounted is None and lock_on:
            for tool in self.desc.tools:
                if self._at_rack(tool):
                    self._mount(tool.name)
                    break

    # -- helpers ------------------------------------------------------------------------
    def _T_world_flange(self) -> np.ndarray:
        w = self.world
        tool_body = w.ids.tool_body
        T = np.eye(4)
        T[:3, :3] = w.data.xmat[tool_body].reshape(3, 3)
        T[:3, 3] = w.data.xpos[tool_body]
        return T

    def _at_rack(self, tool: ChangerTool) -> bool:
        tcp_xyz = (self._T_world_flange() @ tool.T_flange_tcp)[:3, 3]
        return bool(_near_rack(tool, tcp_xyz[None], RACK_TOLERANCE_M)[0])

    def _fit_jaws(self, tool: ChangerTool) -> None:
        """The twin's pair of jaws becomes this tool's: its IO, stroke and place at its TCP."""
        import dataclasses

        w = self.world
        m = w.model
        g = tool.jaws
        w.description = dataclasses.replace(w.description, gripper=g)
        rail = m.body("gripper").id
        m.body_pos[rail] = tool.T_flange_tcp[:3, 3]
        m.body_quat[rail] = quat_of(tool.T_flange_tcp[:3, :3])
        half = g.stroke_m / 2
        for jaw, sign, pad in zip(("jaw_a", "jaw_b"), (1.0, -1.0), w.ids.pad_geoms, strict=True):
            m.jnt_range[m.joint(jaw).id] = (0.0, half)
            m.geom_pos[pad, 0] = sign * (half + g.finger_size_m[0] / 2)
        if w.jaws is not None:
            w.jaws.driven = False

    def _park(self) -> None:
        name = self.mounted
        assert name is not None  # parking takes the mounted tool off
        jaws = self.tools[name].jaws
        if jaws is not None and jaws.closed_sensor_input:
            self.world.inputs[jaws.closed_sensor_input] = False
        self._show(name, mounted=False)
        self._set_gripper(None)
        self._set_payload(0.02, (0.0, 0.0, 0.0))
        self.mounted = None

    def _mount(self, name: str) -> None:

        tool = self.tools[name]
        w = self.world
        m = w.model
        site = w.ids.tcp_site
        m.site_pos[site] = tool.T_flange_tcp[:3, 3]
        m.site_quat[site] = quat_of(tool.T_flange_tcp[:3, :3])
        self._show(name, mounted=True)
        if tool.jaws is not None:
            self._fit_jaws(tool)
        self._set_gripper(tool.gripper)
        self._set_payload(tool.payload_mass_kg, tool.payload_cog_m)
        self.mounted = name

    def _show(self, name: str, mounted: bool) -> None:
        m = self.world.model
        contype, conaffinity = self.tool_kind if mounted else (0, 0)
        for g in self.geoms[name]:
            m.geom_contype[g], m.geom_conaffinity[g] = contype, conaffinity
            m.geom_rgba[g, 3] = 1.0 if mounted else 0.0
        for g in self.rack_geoms[name]:
            m.geom_rgba[g, 3] = 0.0 if mounted else 1.0
        self.world.contacts_changed()

    def _set_gripper(self, kind: str | None) -> None:
        w = self.world
        if w.jaws is not None:
            w.jaws.enabled = kind == "jaws"
        if w.vacuum is not None:
            w.vacuum.set_enabled(kind == "vacuum")
        if w.ids.pad_geoms[0] >= 0:
            bits = self.pad_kind if kind == "jaws" else (0, 0)
            for g in w.ids.pad_geoms:
                w.model.geom_contype[g], w.model.geom_conaffinity[g] = bits
        w.contacts_changed()

    def _set_payload(self, mass_kg: float, cog_m: tuple[float, float, float]) -> None:
        """The tool body's mass (the jaws' fingers keep their own) and the wrist's payload
        compensation, as the controller's setPayload does."""
        w = self.world
        m = w.model
        body = w.ids.tool_body
        below = [b for b in range(m.nbody) if b != body and _descends(m, b, body)]
        fingers = float(sum(m.body_mass[b] for b in below))
        m.body_mass[body] = max(mass_kg - fingers, 0.02)
        m.body_ipos[body] = cog_m
        subtree = float(m.body_mass[body]) + fingers
        m.body_subtreemass[body] = subtree
        w.wrist.tool_weight_N = GRAVITY_MPS2 * subtree


def _near_rack(tool: ChangerTool, tcp_xyz: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Per row of world positions of ``tool``'s TCP (n x 3): within ``tolerance_m`` of its
    rack place."""
    return np.asarray(np.linalg.norm(tcp_xyz - tool.T_world_rack_tcp[:3, 3], axis=1) < tolerance_m)


def _descends(m: Any, body: int, ancestor: int) -> bool:
    while body > 0:
        body = int(m.body_parentid[body])
        if body == ancestor:
            return True
    return False
