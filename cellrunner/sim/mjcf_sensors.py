"""The actuators (arm servos, jaw drives) and sensors (wrist force/torque, what a
look-ahead records) in the MJCF of a cell."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from cellrunner.model.robots import JOINT_NAMES
from cellrunner.sim.mjcf_attrs import fmt
from cellrunner.sim.mjcf_document import MjcfDocument


def add_actuators_and_sensors(builder: MjcfDocument) -> None:
    d = builder.desc
    act = ET.SubElement(builder.root, "actuator")
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
    sensors = ET.SubElement(builder.root, "sensor")
    ET.SubElement(sensors, "force", name="ft_force", site="ft")
    ET.SubElement(sensors, "torque", name="ft_torque", site="ft")
    _add_lookahead_sensors(builder, sensors)


def _add_lookahead_sensors(builder: MjcfDocument, sensors: ET.Element) -> None:
    """What a look-ahead (:mod:`.lookahead`) needs recorded from every physics step,
    as sensors (MuJoCo computes them in C and they do not change the dynamics):
    contact counts (anything on the arm and tool, one part on each finger pad, one
    part on anything; the part is chosen before each look-ahead), the frame of the
    wrist sensor and the tool's centre of mass (the wrench reading), the TCP with a
    tool changer (parking at a rack place) and each part's position (presence sensors
    and ``part_at`` rules)."""
    d = builder.desc
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
