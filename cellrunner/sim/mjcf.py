"""Build the MJCF model of a cell from a :class:`TwinDescription`, and compile it.

Model layout (names are what :mod:`.model_ids` looks up):

- ``base`` body at ``T_world_base``; ``link1``..``link6`` form the DH chain, each body's
  frame being "DH frame i-1 turned by joint i" -- exactly the frame of the arm's convex
  parts (:mod:`cellrunner.model.arm_geometry`), so the twin collides with the very parts
  planning uses (mesh geoms ``arm<body>_<k>``; MuJoCo takes a mesh's convex hull, and each
  part is convex).
  Hinge joints are named as :data:`cellrunner.model.robots.JOINT_NAMES`.
- ``flange`` (DH frame 6) -> ``tool`` body (welded; carries the tool geometry, the
  payload inertia, the ``ft`` site of the wrist force/torque sensor and the ``tcp`` site)
  -> ``jaw_a``/``jaw_b`` finger bodies on slide joints along the TCP's X axis.
- parts: free bodies ``part:<name>``; fixtures: static geoms ``fixture:<name>``; a floor.

Collision bits (contype / conaffinity): 1 static world, 2 robot arm, 4 finger pads,
8 parts, 16 the cell's tool geometry. The tool geometry is the envelope planning checks
against fixtures (it often reaches down around the fingers to the TCP), so in the twin it
collides with fixtures only; the finger pads are what touches parts. The arm does not collide with itself (planning proves that); the base
link collides with nothing (it never moves and sits on its mount).

Arm actuation: one position servo per joint with stiffness kp and damping kv; the world
commands ``q_ref + kv/kp * qd_ref`` so the servo law is
``tau = kp (q_ref - q) + kv (qd_ref - qd)`` (PD with velocity feed-forward). Arm bodies
carry MuJoCo gravity compensation, as the controller's dynamic model does. The gains are
set after compiling, from the joint-space inertia at home, for a natural frequency of
``servo_bandwidth_hz`` critically damped (see :func:`tune_servo_gains`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.model.arm_geometry import arm_geometry
from cellrunner.model.geometry import Box, Cylinder, Mesh, Placed, Shape, Sphere
from cellrunner.model.robots import JOINT_NAMES
from cellrunner.planning.stl import binary_stl, stl_triangles
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.mjcf_attrs import (
    PADS,
    PART_HITS,
    PARTS,
    ROBOT,
    STATIC,
    TOOL,
    ShapeAttrs,
    fmt,
    pose_attrs,
)
from cellrunner.sim.mujoco_loader import load_mujoco
from cellrunner.sim.rigid_contacts import rigid_contact_attrs
from cellrunner.sim.tool_changer import add_tools
from cellrunner.sim.vacuum import add_cups, add_welds

# Arm masses (kg) and joint torque limits (N m, base..wrist 3), datasheets / UR manuals.
ARM_MASS_KG = {
    "ur3": 11.0,
    "ur5": 18.4,
    "ur10": 28.9,
    "ur3e": 11.2,
    "ur5e": 20.6,
    "ur10e": 33.5,
    "ur16e": 33.1,
    "ur7e": 20.6,  # the UR5e renamed
    "ur12e": 33.5,  # the UR10e renamed
    "ur15": 40.2,  # sums of ur_description's link masses (UR15, UR18); UR8 Long assumed
    "ur18": 39.5,
    "ur8long": 42.0,
    "ur20": 64.0,  # datasheets
    "ur30": 63.5,
}
_TORQUE_SMALL = (56.0, 56.0, 28.0, 12.0, 12.0, 12.0)
_TORQUE_MEDIUM = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)
_TORQUE_LARGE = (330.0, 330.0, 150.0, 56.0, 56.0, 56.0)
_TORQUE_UR18 = (433.0, 433.0, 204.0, 70.0, 70.0, 70.0)  # ur_description max_effort
_TORQUE_UR20 = (738.0, 738.0, 433.0, 107.0, 107.0, 107.0)  # ur_description max_effort
JOINT_TORQUE_MAX_NM = {
    "ur3": _TORQUE_SMALL,
    "ur3e": _TORQUE_SMALL,
    "ur5": _TORQUE_MEDIUM,
    "ur5e": _TORQUE_MEDIUM,
    "ur10": _TORQUE_LARGE,
    "ur10e": _TORQUE_LARGE,
    "ur16e": _TORQUE_LARGE,
    "ur7e": _TORQUE_MEDIUM,
    "ur12e": _TORQUE_LARGE,
    "ur15": _TORQUE_UR18,  # assumed: the UR18's joint sizes (same DH d1, d4-d6)
    "ur18": _TORQUE_UR18,
    "ur8long": _TORQUE_UR18,  # assumed, as the UR15
    "ur20": _TORQUE_UR20,
    "ur30": _TORQUE_UR20,
}
# Reflected rotor inertia of the harmonic drives (kg m^2), scaled by arm size.
_ARMATURE_UR5 = (0.6, 0.6, 0.3, 0.06, 0.06, 0.06)


@dataclass(frozen=True)
class PhysicsOptions:
    """Integration settings; the defaults are what bench/bench_sim.py measured as good."""

    max_timestep_s: float = 0.002  # physics steps per period: ceil(period / this)
    servo_bandwidth_hz: float = 40.0  # arm servo natural frequency (capped by stability)
    solver_iterations: int = 20
    cone: str = "elliptic"
    impratio: float = 1.0  # 10 made held parts chatter and fly off during lifts (see tests/sim)
    # MuJoCo's soft friction lets a gripped part creep down the pads under its weight
    # (~0.8 mm/s, so a part held through a 5 s protective stop hung 4 mm lower); the
    # no-slip pass removes that creep
    noslip_iterations: int = 3
    # MuJoCo island sleeping: ~+20% RTF, but the wrist weight read 9% high with it; off.
    sleep: bool = False


def build_mjcf(desc: TwinDescription, options: PhysicsOptions = PhysicsOptions()) -> str:
    """The cell as an MJCF XML string (meshes referenced as in-memory assets)."""
    return _Builder(desc, options).build()


def build_mjcf_with_assets(
    desc: TwinDescription, options: PhysicsOptions = PhysicsOptions()
) -> tuple[str, dict[str, bytes]]:
    """The MJCF XML and its mesh assets (binary STL bytes by asset file name)."""
    builder = _Builder(desc, options)
    xml = builder.build()
    return xml, builder.mesh_files


def compile_model(desc: TwinDescription, options: PhysicsOptions = PhysicsOptions()) -> Any:
    """Compile the MJCF of ``desc`` into an ``mujoco.MjModel`` with tuned servo gains."""
    mujoco = load_mujoco()
    xml, assets = build_mjcf_with_assets(desc, options)
    try:
        model = mujoco.MjModel.from_xml_string(xml, assets)
    except ValueError as exc:  # mujoco reports XML/compile errors as ValueError
        raise ValueError(f"cannot build the twin of cell {desc.name!r}: {exc}") from exc
    tune_servo_gains(model, desc, options)
    return model


def tune_servo_gains(model: Any, desc: TwinDescription, options: PhysicsOptions) -> None:
    """Set kp, kv of the arm servos from the joint-space inertia diagonal at home.

    kp_i = M_ii wn^2, kv_i = 2 M_ii wn (critical damping). wn is capped at 0.5/dt: the
    stiffness is integrated explicitly (damping implicitly), so wn*dt must stay small.
    """
    mujoco = load_mujoco()
    data = mujoco.MjData(model)
    for i, name in enumerate(JOINT_NAMES):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = desc.q_home_rad[i]
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    wn = min(2 * math.pi * options.servo_bandwidth_hz, 0.5 / model.opt.timestep)
    for name in JOINT_NAMES:
        dof = model.jnt_dofadr[model.joint(name).id]
        act = model.actuator(f"servo:{name}").id
        kp, kv = M[dof, dof] * wn**2, 2.0 * M[dof, dof] * wn
        model.actuator_gainprm[act, 0] = kp
        model.actuator_biasprm[act, 1] = -kp
        model.actuator_biasprm[act, 2] = -kv


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


class _Builder:
    def __init__(self, desc: TwinDescription, options: PhysicsOptions) -> None:
        self.desc = desc
        self.options = options
        self.root = ET.Element("mujoco", model=desc.name)
        self.assets: ET.Element | None = None
        self._meshes: dict[str, str] = {}
        self.mesh_files: dict[str, bytes] = {}

    def build(self) -> str:
        d, o = self.desc, self.options
        ET.SubElement(
            self.root,
            "compiler",
            angle="radian",
            autolimits="true",
            inertiafromgeom="auto",
            fusestatic="false",
        )
        substeps = max(1, math.ceil(1.0 / d.rate_hz / o.max_timestep_s - 1e-9))
        self.timestep_s = 1.0 / d.rate_hz / substeps
        # Grasp contacts (pads, parts) as stiff as the step allows (time constant 2 dt):
        # softer ones let a gripped part creep and spring away when the jaws open.
        self.grasp_solref = f"{2 * self.timestep_s:.6g} 1"
        option = ET.SubElement(
            self.root,
            "option",
            timestep=f"{self.timestep_s:.9g}",
            integrator="implicitfast",
            cone=o.cone,
            impratio=f"{o.impratio:g}",
            solver="Newton",
            iterations=str(o.solver_iterations),
            ls_iterations="10",
            tolerance="1e-8",
            noslip_iterations=str(o.noslip_iterations),
            gravity="0 0 -9.81",
        )
        if o.sleep:  # parts at rest stop costing solver time until something touches them
            ET.SubElement(option, "flag", sleep="enable")
        visual = ET.SubElement(self.root, "visual")
        ET.SubElement(visual, "global", offwidth="1600", offheight="1200")
        ET.SubElement(visual, "quality", shadowsize="2048", offsamples="4")
        # a wider shadow clip than the default avoids shadow acne on the floor far out
        ET.SubElement(visual, "map", shadowclip="3", shadowscale="0.6")
        ET.SubElement(
            visual,
            "headlight",
            ambient="0.35 0.35 0.35",
            diffuse="0.5 0.5 0.5",
            specular="0.1 0.1 0.1",
        )
        self._assets()
        world = ET.SubElement(self.root, "worldbody")
        ET.SubElement(
            world,
            "light",
            name="sun",
            pos="0 0 4",
            dir="0.2 0.3 -1",
            directional="true",
            diffuse="0.6 0.6 0.6",
            castshadow="true",
        )
        if d.floor:
            ET.SubElement(
                world,
                "geom",
                name="floor",
                type="plane",
                size="0 0 0.05",
                material="floor",
                contype=str(STATIC),
                conaffinity=str(ROBOT | PADS | PARTS),
            )
        for fixture in d.fixtures:
            self._static_geom(world, fixture)
        self._arm(world)
        for part in d.parts:
            self._part(world, part)
        if d.vacuum is not None and d.parts:
            add_welds(self.root, d.parts)
        if d.cameras or d.markers:
            from cellrunner.sim.cameras import add_cameras

            add_cameras(self, d.cameras, d.markers)
        if d.intruders:
            from cellrunner.sim.depth import add_intruders

            add_intruders(self, d.intruders)
        self._actuators_and_sensors()
        if d.belts:
            from cellrunner.sim.belts import add_belts

            actuators = self.root.find("actuator")
            assert actuators is not None  # written just before
            add_belts(world, actuators, d.belts)
        ET.indent(self.root)
        return ET.tostring(self.root, encoding="unicode")

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

    # -- bodies ---------------------------------------------------------------------
    def _static_geom(self, parent: ET.Element, placed: Placed) -> None:
        shape, T = placed.shape, placed.T_parent_shape
        if isinstance(shape, Mesh) and self._mesh_pieces(parent, placed):
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
            contype=str(STATIC),
            conaffinity=str(ROBOT | PADS | PARTS),
            **self._shape_attrs(shape),
            **pose_attrs(T),
        )
        if placed.name in self.desc.rigid_fixtures:  # a hole's walls (issue 33)
            for key, value in rigid_contact_attrs(self.timestep_s).items():
                geom.set(key, value)

    def _mesh_pieces(self, parent: ET.Element, placed: Placed) -> bool:
        """A non-convex mesh fixture as one thin prism per triangle (see :mod:`.mesh_pieces`);
        False when the mesh is convex (or too big), to be built as usual."""
        from cellrunner.sim import mesh_pieces

        mesh = placed.shape
        assert isinstance(mesh, Mesh)  # called for mesh fixtures
        triangles = stl_triangles(mesh.path) * mesh.scale
        if len(triangles) > mesh_pieces.MAX_TRIANGLES or mesh_pieces.is_convex(triangles):
            return False
        assert self.assets is not None
        for k, vertices in enumerate(mesh_pieces.prisms(triangles)):
            name = f"{placed.name}_piece{k}"
            ET.SubElement(self.assets, "mesh", name=name, vertex=fmt(vertices))
            ET.SubElement(
                parent,
                "geom",
                name=f"fixture:{placed.name}:{k}",
                material="fixture",
                type="mesh",
                mesh=name,
                contype=str(STATIC),
                conaffinity=str(ROBOT | PADS | PARTS),
                **pose_attrs(placed.T_parent_shape),
            )
        return True

    def _arm(self, world: ET.Element) -> None:
        d = self.desc
        spec = d.spec
        parts = arm_geometry(spec.arm).parts
        volume = sum(p.volume_m3 for p in parts if p.body > 0)
        density = ARM_MASS_KG.get(spec.name, 20.0) / volume
        scale = (spec.reach_m / 0.85) ** 2
        torque = JOINT_TORQUE_MAX_NM.get(spec.name, _TORQUE_MEDIUM)
        body = ET.SubElement(world, "body", name="base", **pose_attrs(d.T_world_base))
        parent = body
        for i in range(7):
            if i > 0:
                T = np.eye(4)
                if i > 1:
                    T[:3, 3] = (spec.a_m[i - 2], 0.0, spec.d_m[i - 2])
                    ca, sa = math.cos(spec.alpha_rad[i - 2]), math.sin(spec.alpha_rad[i - 2])
                    T[:3, :3] = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
                body = ET.SubElement(parent, "body", name=f"link{i}", gravcomp="1", **pose_attrs(T))
                ET.SubElement(
                    body,
                    "joint",
                    name=JOINT_NAMES[i - 1],
                    type="hinge",
                    axis="0 0 1",
                    armature=f"{_ARMATURE_UR5[i - 1] * scale:.6g}",
                    damping="0.5",
                    range=fmt(np.radians([spec.joint_min_deg[i - 1], spec.joint_max_deg[i - 1]])),
                    actuatorfrcrange=fmt([-torque[i - 1], torque[i - 1]]),
                )
            assert self.assets is not None
            for k, part in enumerate(x for x in parts if x.body == i):
                bits = (0, 0) if i == 0 else (ROBOT, STATIC | PARTS)
                name = f"arm{i}_{k}"
                ET.SubElement(self.assets, "mesh", name=name, vertex=fmt(part.vertices_m.ravel()))
                ET.SubElement(
                    body,
                    "geom",
                    name=name,
                    type="mesh",
                    mesh=name,
                    density=f"{density if i > 0 else 0:.6g}",
                    material="arm",
                    contype=str(bits[0]),
                    conaffinity=str(bits[1]),
                )
            parent = body
        flange_T = np.eye(4)
        flange_T[:3, 3] = (spec.a_m[5], 0.0, spec.d_m[5])
        ca, sa = math.cos(spec.alpha_rad[5]), math.sin(spec.alpha_rad[5])
        flange_T[:3, :3] = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        flange = ET.SubElement(parent, "body", name="flange", gravcomp="1", **pose_attrs(flange_T))
        ET.SubElement(flange, "inertial", pos="0 0 0", mass="1e-3", diaginertia="1e-7 1e-7 1e-7")
        self._tool(flange)

    def _tool(self, flange: ET.Element) -> None:
        d = self.desc
        g = d.gripper
        fingers_kg = 2 * g.finger_mass_kg if g is not None else 0.0
        tool_kg = max(d.payload_mass_kg - fingers_kg, 0.02)
        tool = ET.SubElement(flange, "body", name="tool", gravcomp="1")
        r = 0.03  # inertia of the payload as a 3 cm radius solid sphere at its cog
        ET.SubElement(
            tool,
            "inertial",
            pos=fmt(d.payload_cog_m),
            mass=f"{tool_kg:.6g}",
            diaginertia=fmt([0.4 * tool_kg * r * r] * 3),
        )
        ET.SubElement(tool, "site", name="ft", pos="0 0 0", size="0.01", rgba="0 0 0 0")
        ET.SubElement(
            tool, "site", name="tcp", size="0.006", rgba="1 0 0 0.6", **pose_attrs(d.T_flange_tcp)
        )
        for k, placed in enumerate(d.tool_geometry):
            ET.SubElement(
                tool,
                "geom",
                name=f"tool:{placed.name or k}",
                material="tool",
                density="0",
                contype=str(TOOL),
                conaffinity=str(STATIC),
                **self._shape_attrs(placed.shape),
                **pose_attrs(placed.T_parent_shape),
            )
        if g is not None:
            self._gripper(tool, g)
        if d.vacuum is not None:
            T = d.vacuum.T_flange_tcp if d.vacuum.T_flange_tcp is not None else d.T_flange_tcp
            add_cups(self, tool, d.vacuum, T, PADS, STATIC | PARTS)
        if d.tool_changer is not None:
            worldbody = self.root.find("worldbody")
            assert worldbody is not None  # built before the tool
            add_tools(self, tool, worldbody, d.tool_changer, TOOL, STATIC)

    def _gripper(self, tool: ET.Element, g: Any) -> None:
        d = self.desc
        t, w, _ = g.finger_size_m
        z0, z1 = g.pad_z_m
        half_stroke = g.stroke_m / 2
        # Visual rail across the fingers' tops, fixed to the tool at the TCP frame.
        T_flange_jaws = g.T_flange_tcp if g.T_flange_tcp is not None else d.T_flange_tcp
        rail = ET.SubElement(tool, "body", name="gripper", **pose_attrs(T_flange_jaws))
        ET.SubElement(
            rail,
            "geom",
            name="gripper:rail",
            type="box",
            material="tool",
            pos=fmt([0, 0, z0 - 0.02]),
            size=fmt([half_stroke + t + 0.01, w / 2 + 0.004, 0.008]),
            contype="0",
            conaffinity="0",
            density="0",
            group="1",
        )
        ET.SubElement(rail, "inertial", pos="0 0 0", mass="1e-3", diaginertia="1e-7 1e-7 1e-7")
        for jaw, sign in (("jaw_a", 1.0), ("jaw_b", -1.0)):
            body = ET.SubElement(rail, "body", name=jaw)
            ET.SubElement(
                body,
                "joint",
                name=jaw,
                type="slide",
                axis=fmt([-sign, 0, 0]),
                range=fmt([0.0, half_stroke]),
                armature="0.2",
                solreflimit="0.004 1",
                solimplimit="0.99 0.999 0.001",
                damping=f"{g.grip_force_N / g.jaw_speed_mps:.6g}",
            )
            x = sign * (half_stroke + t / 2)
            ET.SubElement(
                body,
                "geom",
                name=f"pad:{jaw}",
                type="box",
                material="pad",
                pos=fmt([x, 0, (z0 + z1) / 2]),
                size=fmt([t / 2, w / 2, (z1 - z0) / 2]),
                friction=f"{g.friction:g} 0.01 0.0001",
                condim="4",
                solref=self.grasp_solref,
                contype=str(PADS),
                conaffinity=str(STATIC | PARTS),
                mass=f"{g.finger_mass_kg:.6g}",
            )
            ET.SubElement(
                body,
                "geom",
                name=f"stem:{jaw}",
                type="box",
                material="tool",
                pos=fmt([x, 0, z0 - 0.012]),
                size=fmt([t / 2, w / 2, 0.012]),
                contype="0",
                conaffinity="0",
                density="0",
                group="1",
            )
        eq = self.root.find("equality")
        if eq is None:
            eq = ET.SubElement(self.root, "equality")
        ET.SubElement(
            eq,
            "joint",
            name="jaw_sync",
            joint1="jaw_a",
            joint2="jaw_b",
            solref=f"{2 * self.timestep_s:.6g} 1",
        )

    def _part(self, world: ET.Element, part: Any) -> None:
        feed = self.desc.feed
        # a copy waiting to be fed (sim.feed) floats, touching nothing, until it is fed
        parked = feed is not None and part.name in feed.copies
        body = ET.SubElement(
            world, "body", name=f"part:{part.name}", **pose_attrs(part.T_world_part)
        )
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
            solref=self.grasp_solref,
            contype="0" if parked else str(PARTS),
            conaffinity="0" if parked else str(PART_HITS),
            **self._shape_attrs(part.shape),
        )

    def _actuators_and_sensors(self) -> None:
        d = self.desc
        act = ET.SubElement(self.root, "actuator")
        for name in JOINT_NAMES:
            # kp/kv placeholders; tune_servo_gains sets them from the compiled inertia.
            ET.SubElement(act, "position", name=f"servo:{name}", joint=name, kp="1", kv="1")
        g = d.gripper
        if g is not None:
            # Pneumatic-like jaws: a constant force, with viscous damping on the slide
            # (joint damping) that limits the free closing speed to jaw_speed_mps.
            for jaw in ("jaw_a", "jaw_b"):
                ET.SubElement(
                    act,
                    "motor",
                    name=f"drive:{jaw}",
                    joint=jaw,
                    gear="1",
                    ctrlrange=fmt([-g.grip_force_N, g.grip_force_N]),
                )
        sensors = ET.SubElement(self.root, "sensor")
        ET.SubElement(sensors, "force", name="ft_force", site="ft")
        ET.SubElement(sensors, "torque", name="ft_torque", site="ft")
        self._lookahead_sensors(sensors)

    def _lookahead_sensors(self, sensors: ET.Element) -> None:
        """What a look-ahead (:mod:`.lookahead`) needs recorded from every physics step,
        as sensors (MuJoCo computes them in C and they do not change the dynamics):
        contact counts (anything on the arm and tool, one part on each finger pad, one
        part on anything; the part is chosen before each look-ahead), the frame of the
        wrist sensor and the tool's centre of mass (the wrench reading), the TCP with a
        tool changer (parking at a rack place) and each part's position (presence sensors
        and ``part_at`` rules)."""
        d = self.desc
        ET.SubElement(sensors, "contact", name="ahead:arm", subtree1="base", data="found")
        if d.parts:
            first = f"part:{d.parts[0].name}"
            if d.gripper is not None:
                for jaw in ("jaw_a", "jaw_b"):
                    ET.SubElement(
                        sensors,
                        "contact",
                        name=f"ahead:pad_{jaw[-1]}",
                        geom1=f"pad:{jaw}",
                        geom2=first,
                        data="found",
                    )
            ET.SubElement(sensors, "contact", name="ahead:part", geom1=first, data="found")
        for axis in ("x", "y", "z"):
            ET.SubElement(
                sensors, f"frame{axis}axis", name=f"ahead:ft_{axis}", objtype="site", objname="ft"
            )
        ET.SubElement(sensors, "framepos", name="ahead:ft_pos", objtype="site", objname="ft")
        ET.SubElement(sensors, "subtreecom", name="ahead:tool_com", body="tool")
        if d.tool_changer is not None:  # where the mounted tool's TCP is (its rack place?)
            ET.SubElement(sensors, "framepos", name="ahead:tcp", objtype="site", objname="tcp")
        for part in d.parts:
            ET.SubElement(
                sensors,
                "framepos",
                name=f"ahead:part:{part.name}",
                objtype="body",
                objname=f"part:{part.name}",
            )
