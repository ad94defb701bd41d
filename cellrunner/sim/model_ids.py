"""Indices into a compiled twin model, looked up once by the names :mod:`.mjcf` gives:
the arm's joints and servos, the jaws, the parts, the tool body, sites and the wrist
sensor."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.model.robots import JOINT_NAMES
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.mjcf_attrs import geom_kind as geom_kind_of


@dataclass
class ModelIds:
    qpos: np.ndarray
    dof: np.ndarray
    servo: np.ndarray
    ff_gain: np.ndarray  # kv/kp per arm servo
    jaw_qpos: np.ndarray
    jaw_dof: np.ndarray
    jaw_act: np.ndarray
    pad_geoms: tuple[int, int]
    pad_friction: np.ndarray
    part_bodies: dict[str, int]
    part_qpos: dict[str, int]
    part_geom: dict[str, int]
    part_friction: dict[str, np.ndarray]
    geom_kind: np.ndarray  # STATIC / ROBOT / PADS / PARTS per geom, 0 for none
    tool_body: int
    ft_site: int
    tcp_site: int
    force_adr: int
    torque_adr: int
    tool_mass_kg: float


def lookup_ids(m: Any, d: TwinDescription) -> ModelIds:
    """The indices of compiled model ``m`` built from description ``d``."""
    joints = [m.joint(n).id for n in JOINT_NAMES]
    servo = np.array([m.actuator(f"servo:{n}").id for n in JOINT_NAMES])
    kp = m.actuator_gainprm[servo, 0]
    kv = -m.actuator_biasprm[servo, 2]
    geom_kind = np.zeros(m.ngeom, dtype=int)
    for g in range(m.ngeom):
        geom_kind[g] = geom_kind_of(int(m.geom_contype[g]), int(m.geom_conaffinity[g]))
    gripper = d.gripper is not None
    jaws = [m.joint(j).id for j in ("jaw_a", "jaw_b")] if gripper else []
    pads = (m.geom("pad:jaw_a").id, m.geom("pad:jaw_b").id) if gripper else (-1, -1)
    tool = m.body("tool").id
    return ModelIds(
        qpos=m.jnt_qposadr[joints].copy(),
        dof=m.jnt_dofadr[joints].copy(),
        servo=servo,
        ff_gain=kv / kp,
        jaw_qpos=m.jnt_qposadr[jaws].copy() if gripper else np.zeros(0, int),
        jaw_dof=m.jnt_dofadr[jaws].copy() if gripper else np.zeros(0, int),
        jaw_act=np.array(
            [m.actuator(f"drive:{j}").id for j in ("jaw_a", "jaw_b")] if gripper else [],
            dtype=int,
        ),
        pad_geoms=pads,
        pad_friction=m.geom_friction[list(pads)].copy() if gripper else np.zeros((0, 3)),
        part_bodies={p.name: m.body(f"part:{p.name}").id for p in d.parts},
        part_qpos={p.name: int(m.jnt_qposadr[m.joint(f"part:{p.name}").id]) for p in d.parts},
        part_geom={p.name: m.geom(f"part:{p.name}").id for p in d.parts},
        part_friction={
            p.name: m.geom_friction[m.geom(f"part:{p.name}").id].copy() for p in d.parts
        },
        geom_kind=geom_kind,
        tool_body=tool,
        ft_site=m.site("ft").id,
        tcp_site=m.site("tcp").id,
        force_adr=int(m.sensor_adr[m.sensor("ft_force").id]),
        torque_adr=int(m.sensor_adr[m.sensor("ft_torque").id]),  # == force_adr + 3
        tool_mass_kg=float(m.body_subtreemass[tool]),
    )
