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

from cellrunner.model.robots import JOINT_NAMES
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.jaw_welds import add_jaw_welds
from cellrunner.sim.mjcf_arm import add_arm
from cellrunner.sim.mjcf_attrs import PADS, PARTS, ROBOT, STATIC
from cellrunner.sim.mjcf_bodies import FLAT_MESH_M as FLAT_MESH_M
from cellrunner.sim.mjcf_bodies import add_fixture, add_part
from cellrunner.sim.mjcf_document import MjcfDocument
from cellrunner.sim.mjcf_sensors import add_actuators_and_sensors
from cellrunner.sim.mujoco_loader import load_mujoco
from cellrunner.sim.vacuum import add_welds


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


#: how near a camera's lens the twin draws what stands in front of it (m)
CAMERA_NEAR_M = 0.002


def compile_model(desc: TwinDescription, options: PhysicsOptions = PhysicsOptions()) -> Any:
    """Compile the MJCF of ``desc`` into an ``mujoco.MjModel`` with tuned servo gains."""
    mujoco = load_mujoco()
    xml, assets = build_mjcf_with_assets(desc, options)
    try:
        model = mujoco.MjModel.from_xml_string(xml, assets)
    except ValueError as exc:  # mujoco reports XML/compile errors as ValueError
        raise ValueError(f"cannot build the twin of cell {desc.name!r}: {exc}") from exc
    tune_servo_gains(model, desc, options)
    # the cameras' near clipping plane (MuJoCo's default: 1 % of the model's extent, 24 mm
    # in a generated cell): a body nearer the lens than that was not drawn, and a wrist
    # camera saw the marker through the jaws' rail 7 mm in front of it, which check's line
    # of sight (planning/align_proof.py) rightly finds in the way
    model.vis.map.znear = CAMERA_NEAR_M / max(float(model.stat.extent), CAMERA_NEAR_M)
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


class _Builder(MjcfDocument):
    """Writes the sections of the MJCF in MuJoCo's order; each concern's bodies, actuators
    and sensors come from its module (:mod:`.mjcf_arm`, :mod:`.mjcf_bodies`,
    :mod:`.mjcf_sensors`, cameras, intruders, vacuum, tool changer, belts)."""

    def __init__(self, desc: TwinDescription, options: PhysicsOptions) -> None:
        super().__init__(desc)
        self.options = options

    def build(self) -> str:
        self._header()
        self._assets()
        self._world()
        ET.indent(self.root)
        return ET.tostring(self.root, encoding="unicode")

    def _header(self) -> None:
        """The compiler, the physics options (the step from the control rate) and the
        visual settings."""
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

    def _world(self) -> None:
        """The world body (light, floor, fixtures, arm, parts, cameras, intruders), then
        the actuators and sensors, then the belts."""
        d = self.desc
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
            add_fixture(self, world, fixture)
        add_arm(self, world)
        for part in d.parts:
            add_part(self, world, part)
        if d.vacuum is not None and d.parts:
            add_welds(self.root, d.parts)
        if d.gripper is not None and d.parts:
            add_jaw_welds(self.root, d.parts)
        if d.cameras or d.markers:
            from cellrunner.sim.cameras import add_cameras

            add_cameras(self, d.cameras, d.markers)
        if d.intruders:
            from cellrunner.sim.depth import add_intruders

            add_intruders(self, d.intruders)
        add_actuators_and_sensors(self)
        if d.belts:
            from cellrunner.sim.belts import add_belts

            actuators = self.root.find("actuator")
            assert actuators is not None  # written just before
            add_belts(world, actuators, d.belts)
