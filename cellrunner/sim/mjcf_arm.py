"""The arm, its tool and its gripper in the MJCF of a cell (see :mod:`.mjcf` for the
layout): ``base``, ``link1``..``link6`` on the DH chain, ``flange`` -> ``tool`` -> jaws."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np

from cellrunner.model.arm_dynamics import ARM_MASS_KG, armature_kgm2, joint_torque_max_nm
from cellrunner.model.arm_geometry import arm_geometry
from cellrunner.model.gripper import jaw_frame
from cellrunner.model.robots import JOINT_NAMES
from cellrunner.sim.mjcf_attrs import PADS, PARTS, ROBOT, STATIC, TOOL, fmt, pose_attrs
from cellrunner.sim.mjcf_document import MjcfDocument
from cellrunner.sim.tool_changer import add_tools
from cellrunner.sim.vacuum import add_cups


def add_arm(builder: MjcfDocument, world: ET.Element) -> None:
    d = builder.desc
    spec = d.spec
    parts = arm_geometry(spec.arm).parts
    volume = sum(p.volume_m3 for p in parts if p.body > 0)
    density = ARM_MASS_KG.get(spec.name, 20.0) / volume
    armature = armature_kgm2(spec)
    torque = joint_torque_max_nm(spec)
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
                armature=f"{armature[i - 1]:.6g}",
                damping="0.5",
                range=fmt(np.radians([spec.joint_min_deg[i - 1], spec.joint_max_deg[i - 1]])),
                actuatorfrcrange=fmt([-torque[i - 1], torque[i - 1]]),
            )
        assert builder.assets is not None
        for k, part in enumerate(x for x in parts if x.body == i):
            bits = (0, 0) if i == 0 else (ROBOT, STATIC | PARTS)
            name = f"arm{i}_{k}"
            ET.SubElement(builder.assets, "mesh", name=name, vertex=fmt(part.vertices_m.ravel()))
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
    _add_tool(builder, flange)


def _add_tool(builder: MjcfDocument, flange: ET.Element) -> None:
    d = builder.desc
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
            **builder._shape_attrs(placed.shape),
            **pose_attrs(placed.T_parent_shape),
        )
    if g is not None:
        _add_gripper(builder, tool, g)
    if d.vacuum is not None:
        T = d.vacuum.T_flange_tcp if d.vacuum.T_flange_tcp is not None else d.T_flange_tcp
        add_cups(builder, tool, d.vacuum, T, PADS, STATIC | PARTS)
    if d.tool_changer is not None:
        worldbody = builder.root.find("worldbody")
        assert worldbody is not None  # built before the tool
        add_tools(builder, tool, worldbody, d.tool_changer, TOOL, STATIC)


def _add_gripper(builder: MjcfDocument, tool: ET.Element, g: Any) -> None:
    d = builder.desc
    t, w, _ = g.finger_size_m
    z0, z1 = g.pad_z_m
    half_stroke = g.stroke_m / 2
    # The jaws' frame (model.gripper.jaw_frame: what a wrist camera sees, and check with
    # it): a rail across the fingers' tops, fixed to the tool at the TCP frame, and each
    # finger's stem (moving with it); drawn, not in contact
    (_, rail_c, rail_size), *stems = jaw_frame(g.stroke_m, g.finger_size_m, g.pad_z_m)
    T_flange_jaws = g.T_flange_tcp if g.T_flange_tcp is not None else d.T_flange_tcp
    rail = ET.SubElement(tool, "body", name="gripper", **pose_attrs(T_flange_jaws))
    ET.SubElement(
        rail,
        "geom",
        name="gripper:rail",
        type="box",
        material="tool",
        pos=fmt(rail_c),
        size=fmt(rail_size / 2),
        contype="0",
        conaffinity="0",
        density="0",
        group="1",
    )
    ET.SubElement(rail, "inertial", pos="0 0 0", mass="1e-3", diaginertia="1e-7 1e-7 1e-7")
    for (jaw, sign), (_, stem_c, stem_size) in zip(
        (("jaw_a", 1.0), ("jaw_b", -1.0)), stems, strict=True
    ):
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
            solref=builder.grasp_solref,
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
            pos=fmt(stem_c),
            size=fmt(stem_size / 2),
            contype="0",
            conaffinity="0",
            density="0",
            group="1",
        )
    eq = builder.root.find("equality")
    if eq is None:
        eq = ET.SubElement(builder.root, "equality")
    ET.SubElement(
        eq,
        "joint",
        name="jaw_sync",
        joint1="jaw_a",
        joint2="jaw_b",
        solref=f"{2 * builder.timestep_s:.6g} 1",
    )
