"""Suction cups in the twin: a cup seals on a part's face, a weld holds the part while
the pull stays under the holding force, and losing the vacuum drops it.

Model: each cup is a short cylinder on the tool body (collision kind PADS: touching parts
is what cups do; touching a fixture is a contact like any other). Each part has a weld
equality to the tool body, inactive at start. Every period, with the suction output on:

- a cup *seals* when its face is within ``SEAL_GAP_M`` of a part and the cup's axis is
  square to one of the part's faces (within ``SEAL_ANGLE_DEG``); the part's weld is then
  activated at the pose the part has (no jump);
- the weld's force on the part, split into pull along the cup axis and shear across it,
  is held only while ``pull + shear / CUP_FRICTION`` (low-pass filtered, PULL_TAU_S:
  :mod:`cellrunner.model.suction`, the rule check applies too) stays under the holding force; above it the part tears off (and does not seal again
  until suction is switched off and on);
- suction off (or a blow-off pulse) releases at once; ``part_slip`` opens a leak once the
  held part is in the air (the seal is lost until suction is switched off and on again);
  ``grip_miss`` moves the part away as suction comes on.

``vacuum_ok`` (the vacuum switch) reads true while suction is on and a cup seals.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.gripper import (
    CUP_LENGTH_M,
)  # a cup's body above its face, as planning checks it
from cellrunner.model.suction import filter_step, seal_load_N
from cellrunner.sim.mjcf_attrs import PADS, pose_attrs
from cellrunner.sim.weld_pose import add_tool_welds, weld_where_it_is

#: a cup seals on a face this close (m) ...
SEAL_GAP_M = 0.002
#: ... and this square to the cup's axis (deg)

if TYPE_CHECKING:
    from cellrunner.sim.description import PartDescription
SEAL_ANGLE_DEG = 10.0
#: a cup's rubber lip is compliant: its contacts are MuJoCo's default softness, not the
#: stiff grasp contacts of the jaws (a held part hangs on its weld, not on the contact)
CUP_SOLREF = "0.02 1"
#: grip_miss takes away the part whose face is this close (m) to a cup as suction comes on
GRIP_MISS_REACH_M = 0.05


@dataclass(frozen=True)
class VacuumDescription:
    """A vacuum gripper: cups ``(xyz in the TCP frame, radius)``, its IO channels and the
    pull (N) the cups hold."""

    cups: tuple[tuple[tuple[float, float, float], float], ...]
    suction_output: str
    T_flange_tcp: np.ndarray | None = None  # the vacuum tool's TCP (default: the twin's)
    suction_value: bool | float = True
    vacuum_ok_input: str | None = None
    blow_off_output: str | None = None
    holding_force_N: float = 100.0


def add_cups(
    builder: Any,
    tool: ET.Element,
    vac: VacuumDescription,
    T_flange_tcp: np.ndarray,
    pads_kind: int,
    hits: int,
) -> None:
    """The cups as geoms of the tool body (MJCF)."""
    from cellrunner.model import geometry

    for i, ((x, y, z), r) in enumerate(vac.cups):
        T = T_flange_tcp @ geometry.pose_matrix((x, y, z - CUP_LENGTH_M / 2))
        ET.SubElement(
            tool,
            "geom",
            name=f"cup:{i}",
            type="cylinder",
            size=f"{r:.6g} {CUP_LENGTH_M / 2:.6g}",
            material="pad",
            density="0",
            friction="1 0.01 0.0001",
            condim="4",
            solref=CUP_SOLREF,
            contype=str(pads_kind),
            conaffinity=str(hits),
            **pose_attrs(T),
        )


def add_welds(root: ET.Element, parts: Iterable[PartDescription]) -> None:
    """One inactive weld per part, tool to part (MJCF)."""
    add_tool_welds(root, parts, "vac:", solref="0.004 1")


class VacuumCups:
    """The cups of one built SimWorld (constructed after its model is compiled)."""

    def __init__(self, world: Any, vac: VacuumDescription) -> None:
        self.world, self.vac = world, vac
        m = world.model
        self._mj = world.mujoco
        self.cup_geoms = [m.geom(f"cup:{i}").id for i in range(len(vac.cups))]
        self.weld = {name: m.equality(f"vac:{name}").id for name in world.ids.part_bodies}
        self.held: frozenset[str] = frozenset()
        self.suction = False
        self.leak = False
        self.torn: set[str] = set()
        self.grip_miss_armed = False
        self.slip_armed = False
        self._pull_lp: dict[str, float] = {}
        self.last_pull_N = 0.0
        self.enabled = True
        self._cup_bits = [
            (int(m.geom_contype[g]), int(m.geom_conaffinity[g])) for g in self.cup_geoms
        ]

    def set_enabled(self, on: bool) -> None:
        """Mounted (a tool changer took the vacuum tool) or parked: cups collide and seal only when on."""
        self.enabled = on
        m = self.world.model
        for g, bits in zip(self.cup_geoms, self._cup_bits, strict=True):
            m.geom_contype[g], m.geom_conaffinity[g] = bits if on else (0, 0)
            m.geom_rgba[g, 3] = 1.0 if on else 0.0
        if not on:
            self._drop_all()
            self.suction = False

    # -- per period ---------------------------------------------------------------------
    def drive(self) -> None:
        """Follow the suction and blow-off outputs (before the physics step)."""
        w = self.world
        on = self._suction_wanted()
        if on and not self.suction:
            self.leak = False
            self.torn.clear()
            if self.grip_miss_armed:
                self.grip_miss_armed = False
                w.grip_faults.move_part_away(self.cup_geoms, GRIP_MISS_REACH_M)
        self.suction = on
        if not on and self.held:
            self._drop_all()

    def update(self) -> None:
        """Seal, hold or tear off (after the physics step)."""
        if not self.suction or self.leak:
            if self.held:
                self._drop_all()
            return
        for name in list(self.held):
            if self._pull_N(name) > self.vac.holding_force_N:
                self._drop(name)
                self.torn.add(name)  # open to the air: no seal on it until suction is cycled
        if self.slip_armed and any(self._in_air(p) for p in self.held):
            self.slip_armed = False
            self.leak = True
            self._drop_all()
            return
        if not self.held:
            sealed = self._sealed_part()
            if sealed is not None:
                self._weld(sealed)

    @property
    def vacuum_ok(self) -> bool:
        return self.suction and bool(self.held)

    @property
    def idle(self) -> bool:
        """Whether the coming periods leave the cups as they are whatever the arm does:
        suction off and staying off (its outputs as they are now), nothing held."""
        return not self.suction and not self.held and not self._suction_wanted()

    def _suction_wanted(self) -> bool:
        """What the outputs ask for: suction on (blow-off pulses and a parked tool: off)."""
        w, v = self.world, self.vac
        on = self.enabled and w.outputs.get(v.suction_output) == v.suction_value
        if v.blow_off_output is not None and w.outputs.get(v.blow_off_output):
            on = False
        return bool(on)

    # -- helpers ------------------------------------------------------------------------
    def _in_air(self, part: str) -> bool:
        """Held by the cups alone, clear of fixtures and the floor."""

        w = self.world
        return all(
            k == PADS for k in w.contacts.kinds_touching(part)
        ) and w.contacts.clear_of_static(part)

    def _sealed_part(self) -> str | None:
        w = self.world
        m, d = w.model, w.data
        R_tcp = d.site_xmat[w.ids.tcp_site].reshape(3, 3)
        axis = R_tcp[:, 2]
        cos_max = math.cos(math.radians(SEAL_ANGLE_DEG))
        fromto = np.zeros(6)
        for name, geom in w.ids.part_geom.items():
            if name in self.torn:
                continue
            R_part = d.xmat[w.ids.part_bodies[name]].reshape(3, 3)
            if float(np.max(np.abs(R_part.T @ axis))) < cos_max:
                continue
            for cup in self.cup_geoms:
                if self._mj.mj_geomDistance(m, d, cup, geom, 0.01, fromto) < SEAL_GAP_M:
                    return str(name)
        return None

    def _weld(self, name: str) -> None:
        w = self.world
        weld_where_it_is(
            self._mj, w.model, w.data, self.weld[name], w.ids.tool_body, w.ids.part_bodies[name]
        )
        self.held = self.held | {name}
        self._pull_lp[name] = 0.0
        w.contacts_changed_held()

    def _drop(self, name: str) -> None:
        w = self.world
        w.data.eq_active[self.weld[name]] = 0
        self.held = self.held - {name}
        self._pull_lp.pop(name, None)
        w.places.let_go({name})
        w.contacts_changed_held()

    def _drop_all(self) -> None:
        for name in list(self.held):
            self._drop(name)

    def _cups_push(self, name: str) -> np.ndarray:
        """World force (N) of the cups' contacts on part ``name``."""
        w = self.world
        m, d = w.model, w.data
        geom = w.ids.part_geom[name]
        total = np.zeros(3)
        wrench = np.zeros(6)
        for k in range(d.ncon):
            c = d.contact[k]
            g1, g2 = int(c.geom1), int(c.geom2)
            if geom not in (g1, g2) or (g1 if g2 == geom else g2) not in self.cup_geoms:
                continue
            self._mj.mj_contactForce(m, d, k, wrench)
            # the frame's first row is the normal, from geom1 to geom2: the force on geom2
            f = np.asarray(c.frame).reshape(3, 3).T @ wrench[:3]
            total += f if g2 == geom else -f
        return total

    def _pull_N(self, name: str) -> float:
        """The filtered pull on the part's seal: along the cup axis plus shear over friction.

        The seal carries the net force of the tool on the part: the weld's plus the cups'
        contacts. A jolt that presses the part into the cups' lips is resisted by the weld,
        and that fight is internal (the lips squeezed, the seal not pulled): the weld's
        force alone read it as a pull of up to ~190 N at a UR10e set-down and tore a
        0.5 kg box off."""
        w = self.world
        d = w.data
        eq = self.weld[name]
        n = d.nefc
        rows = np.flatnonzero(
            (d.efc_type[:n] == self._mj.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id[:n] == eq)
        )
        if len(rows) < 3:
            return self._pull_lp.get(name, 0.0)
        f_on_part = -np.asarray(d.efc_force[rows[:3]]) + self._cups_push(name)
        axis = d.site_xmat[w.ids.tcp_site].reshape(3, 3)[:, 2]  # out of the cups, into the part
        # pull towards the cups plus shear over friction (model.suction: check's rule too)
        load = float(seal_load_N(f_on_part, axis))
        lp = filter_step(self._pull_lp.get(name, load), load, w.period_s)
        self._pull_lp[name] = lp
        self.last_pull_N = lp
        return lp
