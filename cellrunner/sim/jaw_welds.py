"""The twin's jaws hold a part as their friction does: rigidly, until the load across the
jaw axis beats what the pads hold (issue 33).

MuJoCo's friction is a velocity-level constraint: a part between two pads keeps no
relative velocity, but its position drifts with the integration step while the jaws turn
and accelerate. With the twin's 2 ms step a square pin crept 1.2-2.3 mm across the pads
(and pivoted up to 3.5 deg about the jaw axis) over one carrying move of a second, at
loads a hundredth of the 80 N the pads hold: the same drift with ten times the pads'
friction, four times less with a 0.5 ms step, none on a real gripper. Its tip then met
the rim of a hole with 0.4-1.6 mm of clearance (generated ``hole_fit`` jobs, twelve of
24 of seed 3000, which ``check`` rightly approved).

So a part gripped between both pads is welded to the tool where it sits, the way
suction cups hold theirs (:mod:`.vacuum`), once it touches nothing but the pads (lifted
off what it stood on: a weld made while it still touches a fixture would hold it there
as the pads' friction would not, and drag it; a stick too thin for the jaw sensor, held on
its table while the grip timed out, was knocked over on the retry and carried 48 mm off
its place). It is let go when the jaws are commanded open, when a ``part_slip`` fault
loosens the grip (not welded again until the jaws open: the part slides on the pads'
reduced friction and falls), or when the weld's force on the part across the jaw axis
exceeds :func:`cellrunner.model.jaw_grip.jaws_hold_N` (the rule ``check`` applies,
:mod:`cellrunner.planning.jaw_hold`): then the pads' friction alone holds it and it
slides as before, until it is free of the fixtures again. Along the jaw axis the pads
hold by their clamp, so the force along it never lets go. While a weld holds, the pads'
contacts have no friction (it would fight the weld) and win over the part's; else they
are the pads' own, as with no weld in the model.

The look-ahead (:mod:`.lookahead`) carries the weld through its periods (``eq_active``
is in the state it rolls out) but neither makes one nor judges the load there: it does
not look ahead while a gripped part waits for its weld (:meth:`JawWelds.pending`), and
looks ahead only while the part touches nothing but the pads, where the load is the
part's inertia, which ``check`` keeps under the pads' hold.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.jaw_grip import slip_load_N
from cellrunner.sim.mjcf_attrs import PADS
from cellrunner.sim.weld_pose import add_tool_welds, relative_pose, weld_at

if TYPE_CHECKING:
    from cellrunner.sim.description import PartDescription

#: the MJCF name of part NAME's jaw weld is JAW_WELD_PREFIX + NAME
JAW_WELD_PREFIX = "jaw:"
#: the weld's time constant and damping ratio (as the cups' welds)
JAW_WELD_SOLREF = "0.004 1"
#: ... and its impedance, near 1 (MuJoCo's default 0.9-0.95 left the pads' contacts
#: holding the part 0.2 mm and 0.5 deg off its welded pose after a carry)
JAW_WELD_SOLIMP = "0.99 0.999 0.001"
#: the pads' contact dimension when no weld holds (normal, two tangents, torsion)
PAD_CONDIM = 4


def add_jaw_welds(root: ET.Element, parts: Iterable[PartDescription]) -> None:
    """One inactive weld per part, tool to part (MJCF)."""
    add_tool_welds(root, parts, JAW_WELD_PREFIX, solref=JAW_WELD_SOLREF, solimp=JAW_WELD_SOLIMP)


class JawWelds:
    """The jaw welds of one built SimWorld with jaws (constructed after its model is
    compiled). ``held``: the parts welded now; ``sliding``: the parts let go because the
    load beat the pads' friction, welded again once free of every fixture; ``loosened``:
    the parts a ``part_slip`` fault let go, never welded again until the jaws open (the
    fault loosens this grip: the part slides on the pads' reduced friction and may touch
    them again as it falls, which a real loosened grip does not catch)."""

    def __init__(self, world: Any) -> None:
        self.world = world
        m = world.model
        self._mj = world.mujoco
        self.weld = {
            name: m.equality(f"{JAW_WELD_PREFIX}{name}").id for name in world.ids.part_bodies
        }
        g = world.description.gripper
        self.holds_N = {
            p.name: 2.0 * max(float(g.friction), float(p.friction)) * float(g.grip_force_N)
            for p in world.description.parts
        }
        self.held: set[str] = set()
        self.sliding: set[str] = set()
        self.loosened: set[str] = set()
        self.last_load_N = 0.0
        #: where each gripped part sat in the jaws while the arm stood still (the grip),
        #: until the jaws open: its first weld holds it there
        self.gripped_at: dict[str, np.ndarray] = {}

    def pending(self, gripped: frozenset[str]) -> bool:
        """Whether a gripped part may be welded in a coming period (the look-ahead, which
        makes no weld, stops for it)."""
        return any(
            n in self.weld and n not in self.held and n not in self.loosened for n in gripped
        )

    def busy(self, gripped: frozenset[str]) -> bool:
        """Whether :meth:`update` has anything to do this period."""
        return bool(gripped or self.held or self.loosened)

    def update(self, gripped: frozenset[str], closing: bool, loose: Iterable[str] = ()) -> None:
        """After a period's physics: weld the parts between both pads that touch nothing
        else (those the load let slide: once clear of the fixtures), let go of those the
        jaws open on or whose load across the jaw axis beats the pads' friction. ``loose``:
        parts whose grip a fault loosened (``part_slip``): let go, and not welded again
        until the jaws open."""
        if not closing:
            for name in list(self.held):
                self._drop(name)
            self.sliding.clear()
            self.loosened.clear()
            self.gripped_at.clear()
            return
        self.loosened.update(loose)
        for name in list(self.held):
            if name in self.loosened or not self._still_between_pads(name, gripped):
                self._drop(name)
                continue
            load = self._load_N(name)
            self.last_load_N = load
            if load > self.holds_N.get(name, np.inf):
                self._drop(name)
                self.sliding.add(name)
        for name in gripped:
            if name in self.held or name not in self.weld or name in self.loosened:
                continue
            contacts = self.world.contacts
            if name in self.sliding:
                if not contacts.in_air(name):
                    continue
                self.sliding.discard(name)
                self._weld(name, None)  # where it slid to
                continue
            if self._arm_still():
                self.gripped_at[name] = self._pose_in_tool(name)
            if any(k != PADS for k in contacts.kinds_touching(name)):
                continue
            self._weld(name, self.gripped_at.get(name))

    def _still_between_pads(self, name: str, gripped: frozenset[str]) -> bool:
        """Whether welded part NAME is still in the closed jaws: between both pads, or
        touching one of them. A finger on its slide shakes as the tool accelerates and lets
        go of a welded part's face for a period or two; dropping the weld then and making it
        again where the part had sagged let a 1 kg part creep 1 mm down the pads over one
        carry (s80544: placed 1 mm into its table, 172 N)."""
        return name in gripped or self.world.contacts.touches_pads(name)

    def _load_N(self, name: str) -> float:
        """The weld's force on the part across the jaw axis (the TCP's X), N."""
        w = self.world
        d = w.data
        n = d.nefc
        rows = np.flatnonzero(
            (d.efc_type[:n] == self._mj.mjtConstraint.mjCNSTR_EQUALITY)
            & (d.efc_id[:n] == self.weld[name])
        )
        if len(rows) < 3:
            return 0.0
        f_on_part = -np.asarray(d.efc_force[rows[:3]])
        jaw_axis = d.site_xmat[w.ids.tcp_site].reshape(3, 3)[:, 0]
        return float(slip_load_N(f_on_part, jaw_axis))

    def _weld(self, name: str, pose: np.ndarray | None) -> None:
        """Weld part NAME to the tool at ``pose`` (:func:`relative_pose`: where it sat
        while the arm stood still and the jaws closed on it), or where it is now. The
        pads' soft contacts let a part creep 0.2-0.3 mm along them as the lift drags it
        off its table, before it touches nothing but the pads; welded there, a UR10's pin
        pressed into a fit 0.1 mm tight met a wall 0.31 mm deep (s100652): a real pad's
        friction lets nothing creep."""
        w = self.world
        weld_at(
            w.model, w.data, self.weld[name], pose if pose is not None else self._pose_in_tool(name)
        )
        self.held.add(name)
        self._pads_hold(welded=True)

    def _pose_in_tool(self, name: str) -> np.ndarray:
        w = self.world
        return relative_pose(self._mj, w.data, w.ids.tool_body, w.ids.part_bodies[name])

    def _arm_still(self) -> bool:
        """Whether the arm stands still (its joints under 1 mrad/s)."""
        return bool(np.abs(self.world.data.qvel[0:6]).max() < 1e-3)

    def _drop(self, name: str) -> None:
        self.world.data.eq_active[self.weld[name]] = 0
        self.held.discard(name)
        if not self.held:
            self._pads_hold(welded=False)

    def _pads_hold(self, welded: bool) -> None:
        """The pads' contacts while a weld holds the part: no friction (condim 1), whose
        velocity-level drift would fight the weld, and the pads' parameters winning over
        the part's (priority 1: a contact's condim is otherwise the larger of its two
        geoms'). Else the pads' own: condim PAD_CONDIM and no priority, so their contacts
        with a fixture mix both geoms' stiffness as they do with no weld in the model (with
        the pads' stiffer solref winning, a guarded line onto a block peaked at 38 N for a
        30 N bound)."""
        pads = [int(g) for g in self.world.ids.pad_geoms if int(g) >= 0]
        m = self.world.model
        m.geom_condim[pads] = 1 if welded else PAD_CONDIM
        m.geom_priority[pads] = 1 if welded else 0
