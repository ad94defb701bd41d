"""Contacts in the twin, judged every period as the controller and the line would:

- the arm, tool or pads against a fixture or the floor, or the arm or tool against a part
  it does not hold, harder than the cell's contact force limit over a few periods (as the
  controller filters its force estimate), or three times as hard at once: a protective
  stop;
- a carried part pushed into a fixture (forced back in the jaws, or pressed too hard): a
  protective stop; setting it down lightly is not;
- where each gripped part sits in the jaws while nothing presses it (a part forced back
  in them is jammed); taking hold and letting go are told to :mod:`.places`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cellrunner.model.robot_state import Safety
from cellrunner.sim.mjcf_attrs import PADS, PARTS, ROBOT, STATIC, TOOL, geom_kind
from cellrunner.sim.wrist import GRAVITY_MPS2

if TYPE_CHECKING:
    from cellrunner.sim.description import TwinDescription
    from cellrunner.sim.model_ids import ModelIds
    from cellrunner.sim.places import Places
    from cellrunner.sim.safety import StopReason

AIR_CLEARANCE_M = 0.01  # "in the air": this far from every fixture and the floor
JAM_SLIDE_M = 0.005  # a gripped part forced back this far in the jaws by a fixture: a collision
JAM_FORCE_N = 150.0  # or pressed onto a fixture this hard (UR's default force limit)
#: an unexpected contact stops the arm when its force over the last CONTACT_PERIODS
#: periods averages over the limit, as the controller filters its force estimate (a
#: single period's spike of a stiff contact is no collision), or at once over
#: CONTACT_HARD_FACTOR x the limit
CONTACT_PERIODS = 3
CONTACT_HARD_FACTOR = 3.0

NONE: frozenset[str] = frozenset()


def collided(recent_N: list[float], force_N: float, limit_N: float) -> bool:
    """The controller's verdict on this period's unexpected contact force ``force_N``,
    appended to ``recent_N`` (the periods before, while the contact lasted): over the
    limit on average over ``CONTACT_PERIODS`` periods, or over ``CONTACT_HARD_FACTOR`` x
    the limit at once."""
    recent_N.append(force_N)
    del recent_N[:-CONTACT_PERIODS]
    return force_N > CONTACT_HARD_FACTOR * limit_N or sum(recent_N) / CONTACT_PERIODS > limit_N


@dataclass
class ContactEvent:
    """The unexpected contact that raised a protective stop (for logs and reports)."""

    time_s: float
    force_N: float
    geoms: tuple[str, str]

    def describe(self) -> str:
        """What touched what and how hard, the robot's side first: "pad 'jaw_a' met
        fixture 'infeed_table' at 673 N"."""
        first, second = sorted(self.geoms, key=lambda g: not _robot_side(g))
        return f"{geom_label(first)} met {geom_label(second)} at {self.force_N:.0f} N"


#: the twin's geom names of the robot's side, by prefix: the arm's links, its tool, pads, cups
_ROBOT_PREFIXES = ("arm", "tool:", "tool@", "pad:", "cup:")


def _robot_side(geom: str) -> bool:
    return geom.startswith(_ROBOT_PREFIXES)


def geom_label(geom: str) -> str:
    """A twin's geom name as the cell file names the thing: ``fixture:infeed_table:2`` is
    fixture 'infeed_table', ``arm3_0`` the arm's link 3 (the forearm), ``pad:jaw_a`` pad
    'jaw_a'."""
    kind, _, rest = geom.partition(":")
    name = rest.split(":")[0]
    if kind in ("fixture", "part", "pad") and name:
        return f"{kind} {name!r}"
    if kind == "cup" and name:
        return f"cup {name}"
    if kind == "tool" and name:
        return f"the tool's {name!r}"
    if geom.startswith(("tool@", "rack@")):
        tool = geom.partition("@")[2].rsplit(":", 1)[0]
        return f"tool {tool!r}" if geom.startswith("tool@") else f"the rack of tool {tool!r}"
    if geom.startswith("arm") and geom[3:4].isdigit():
        link = int(geom[3])
        return f"the arm's link {link} ({_LINKS[link]})" if link < len(_LINKS) else geom
    return f"the {geom}" if geom == "floor" else repr(geom)


#: the arm's bodies, base to wrist 3, as the twin numbers them (``arm{i}_{k}``)
_LINKS = ("base", "shoulder", "upper arm", "forearm", "wrist 1", "wrist 2", "wrist 3")


class ContactWorld(Protocol):
    """What the contact rules see of the twin (:class:`~cellrunner.sim.world.SimWorld`)."""

    description: TwinDescription
    model: Any
    data: Any
    safety: Safety
    last_contact: ContactEvent | None
    places: Places

    @property
    def mujoco(self) -> Any: ...

    @property
    def ids(self) -> ModelIds: ...

    @property
    def time_s(self) -> float: ...

    def tcp_pose_world(self) -> np.ndarray: ...

    def part_pose_world(self, name: str) -> np.ndarray: ...

    def raise_protective_stop(self, reason: StopReason = ...) -> None: ...


class ContactMonitor:
    """The contact rules of one built twin; :meth:`check` runs every period."""

    def __init__(self, world: ContactWorld) -> None:
        self.world = world
        ids = world.ids
        #: gripped part -> T_tcp_part while no fixture presses it
        self.held_at: dict[str, np.ndarray] = {}
        #: whether a carried part touched a fixture in the last check
        self.pressed = False
        self._pad_a = ids.pad_geoms[0]
        self._part_of_geom = {g: name for name, g in ids.part_geom.items()}
        self._part_mass_kg: dict[str, float] = {
            p.name: float(p.mass_kg) for p in world.description.parts
        }
        self._force6 = np.zeros(6)
        #: the unexpected contacts' force (N) of the last periods, while they last
        self._recent_N: list[float] = []
        self._fromto6 = np.zeros(6)
        self._vac_geoms: frozenset[int] = frozenset()  # part geoms the cups hold
        self._kind: list[int] = []
        self._static_geoms: list[int] = []
        self._robot_or_pad_geoms: frozenset[int] = frozenset()
        # geom pairs of the last contact check that found nothing suspicious, and its
        # verdict (the gripped parts)
        self._clean_pairs: list[list[int]] | None = None
        self._clean_gripped: frozenset[str] = NONE
        self.geoms_changed()

    def geoms_changed(self) -> None:
        """Geoms were switched on or off (a tool change): take their collision kinds anew."""
        m = self.world.model
        self._kind = [
            geom_kind(int(m.geom_contype[g]), int(m.geom_conaffinity[g])) for g in range(m.ngeom)
        ]
        self._static_geoms = [g for g, k in enumerate(self._kind) if k == STATIC]
        self._robot_or_pad_geoms = frozenset(
            g for g, k in enumerate(self._kind) if k & (ROBOT | PADS | TOOL)
        )
        self._clean_pairs, self._clean_gripped = None, NONE

    def suction_changed(self, held: frozenset[str]) -> None:
        """The cups sealed on or let go of a part: the verdict on the same contact pairs
        changes (a part held by suction pressed onto a fixture is judged like a gripped one)."""
        self._vac_geoms = frozenset(self.world.ids.part_geom[n] for n in held)
        self._clean_pairs, self._clean_gripped = None, NONE

    def check(self) -> frozenset[str]:
        """Raise a protective stop on unexpected contact; return the gripped parts.

        Unexpected: the arm, tool or pads against a fixture or the floor; the arm or tool
        (not the pads) against a part that is not gripped. Contacts are few, so a plain
        loop over Python ints beats numpy here (this runs every period). Most periods
        see the same geom pairs as the last one (a part resting, a part held), and the
        verdict on pairs with nothing suspicious among them depends on the pairs alone.
        """
        self.pressed = False
        data = self.world.data
        if not data.ncon:
            self._recent_N.clear()
            return NONE
        pairs = data.contact.geom.tolist()
        if pairs == self._clean_pairs:
            self._recent_N.clear()
            return self._clean_gripped
        watched = self._robot_or_pad_geoms | self._vac_geoms
        for g1, g2 in pairs:
            if g1 in watched or g2 in watched:
                break
        else:
            self._clean_pairs, self._clean_gripped = pairs, NONE
            self._recent_N.clear()
            return NONE
        kind = self._kind
        pad_hits: dict[int, int] = {}
        robot_parts: list[tuple[int, int]] = []
        suspicious: list[int] = []
        part_static: list[int] = []
        pad_parts: list[tuple[int, int]] = []
        for i, (g1, g2) in enumerate(pairs):
            k1, k2 = kind[g1], kind[g2]
            both = k1 | k2
            if not both & (ROBOT | PADS | TOOL):
                if both == PARTS | STATIC:
                    part_static.append(i)
                continue
            if both & STATIC:
                suspicious.append(i)
            elif both == PADS | PARTS:
                pad, part = (g1, g2) if k1 == PADS else (g2, g1)
                pad_hits[part] = pad_hits.get(part, 0) | (1 if pad == self._pad_a else 2)
                pad_parts.append((i, part))
            elif both == ROBOT | PARTS:
                robot_parts.append((i, g2 if k2 == PARTS else g1))
        gripped_geoms = {g for g, hits in pad_hits.items() if hits == 3}
        carried = gripped_geoms | self._vac_geoms
        suspicious += [i for i, g in robot_parts if g not in carried]
        # a finger landing on a part it does not hold (judged by force, like the tool);
        # a held part that loses one pad's contact for a moment is still held, and the
        # cups pressing on the part they hold are how suction carries it
        held = self.held_at
        suspicious += [
            i for i, g in pad_parts if g not in carried and self._part_of_geom[g] not in held
        ]
        # a carried part pushed into a fixture is a contact like the tool's own; the
        # light touch of setting it down is not (judged each period, so never cached)
        pressed = [i for i in part_static if pairs[i][0] in carried or pairs[i][1] in carried]
        if pressed and self.world.safety is Safety.NORMAL:
            self._judge_pressed(pressed, gripped_geoms)
        if suspicious and self.world.safety is Safety.NORMAL:
            self._judge_contacts(suspicious)
        else:
            self._recent_N.clear()
        gripped = frozenset(self._part_of_geom[g] for g in gripped_geoms) if gripped_geoms else NONE
        self._clean_pairs, self._clean_gripped = (
            (None, NONE) if suspicious or pressed else (pairs, gripped)
        )
        self.pressed = bool(pressed)
        return gripped

    def _judge_contacts(self, indices: list[int]) -> None:
        w, force = self.world, self._force6
        total, worst, worst_i = 0.0, -1.0, indices[0]
        for i in indices:
            w.mujoco.mj_contactForce(w.model, w.data, i, force)
            total += abs(force[0])
            if abs(force[0]) > worst:
                worst, worst_i = abs(force[0]), i
        if collided(self._recent_N, total, w.description.contact_force_limit_N):
            self._recent_N.clear()
            self._stop_on(worst_i, total)

    def _judge_pressed(self, indices: list[int], gripped_geoms: set[int]) -> None:
        """A gripped part against a fixture: a protective stop when it is forced back in
        the jaws by more than ``JAM_SLIDE_M`` since it was last free of fixtures (pushed
        into the fixture, not set down on it), or pressed harder than ``JAM_FORCE_N`` beyond
        the parts' own weight (a 12 kg case resting on its conveyor while the cups seal is
        not the arm pressing: UR's force limit sees what the arm adds)."""
        w, force = self.world, self._force6
        total = 0.0
        parts: set[str] = set()
        for i in indices:
            w.mujoco.mj_contactForce(w.model, w.data, i, force)
            total += abs(force[0])
            parts.update(
                self._part_of_geom[int(g)]
                for g in w.data.contact.geom[i]
                if int(g) in self._part_of_geom
            )
        total -= GRAVITY_MPS2 * sum(self._part_mass_kg[p] for p in parts)
        slide = max(
            (self._slide_in_jaws_m(self._part_of_geom[g]) for g in gripped_geoms), default=0.0
        )
        if slide > JAM_SLIDE_M or total > JAM_FORCE_N:
            self._stop_on(indices[0], total)

    def _stop_on(self, contact: int, force_N: float) -> None:
        from cellrunner.sim.safety import StopReason

        w = self.world
        g1, g2 = (w.model.geom(int(g)).name for g in w.data.contact.geom[contact])
        w.last_contact = ContactEvent(w.time_s, force_N, (g1, g2))
        w.raise_protective_stop(StopReason.CONTACT)

    # -- held parts ---------------------------------------------------------------------
    def part_in_tcp(self, part: str) -> np.ndarray:
        """T_tcp_part: the part's pose in the TCP frame."""
        T_world_tcp = self.world.tcp_pose_world()
        R_t = T_world_tcp[:3, :3].T
        T_world_part = self.world.part_pose_world(part)
        T = np.eye(4)
        T[:3, :3] = R_t @ T_world_part[:3, :3]
        T[:3, 3] = R_t @ (T_world_part[:3, 3] - T_world_tcp[:3, 3])
        return T

    def _slide_in_jaws_m(self, part: str) -> float:
        """How far the part was forced back in the jaws (towards the flange, or sideways)
        since it was last free of fixtures; sliding out of them (a slip) does not count."""
        held = self.held_at.get(part)
        if held is None:
            return 0.0
        d = self.part_in_tcp(part)[:3, 3] - held[:3, 3]
        return max(-float(d[2]), math.hypot(float(d[0]), float(d[1])))

    def note_held(self, gripped: frozenset[str], closing: bool) -> None:
        """Where each gripped part sits in the jaws while no fixture touches it; kept
        through a period of lost pad contact; the parts let go once the jaws are commanded
        open (``closing`` false) are told to the place check."""
        if not closing:
            if self.held_at:
                self.world.places.let_go(set(self.held_at))
                self.held_at = {}
            return
        if gripped and not self.pressed:
            for name in gripped:
                self.held_at[name] = self.part_in_tcp(name)

    # -- what a part touches --------------------------------------------------------------
    def kinds_touching(self, part: str) -> list[int]:
        """Collision kinds (:mod:`.mjcf` bits) of the geoms the part touches."""
        g = self.world.ids.part_geom[part]
        kind = self._kind
        data = self.world.data
        return [
            kind[g2 if g1 == g else g1]
            for g1, g2 in data.contact.geom[: data.ncon].tolist()
            if g in (g1, g2)
        ]

    def in_air(self, part: str) -> bool:
        """True when the part touches the finger pads only and is clear of the fixtures."""
        kinds = self.kinds_touching(part)
        if not kinds or any(k != PADS for k in kinds):
            return False
        return self.clear_of_static(part)

    def clear_of_static(self, part: str) -> bool:
        """True when the part is ``AIR_CLEARANCE_M`` clear of every fixture and the floor."""
        w = self.world
        g = w.ids.part_geom[part]
        fromto = self._fromto6
        for other in self._static_geoms:
            d = w.mujoco.mj_geomDistance(w.model, w.data, g, other, AIR_CLEARANCE_M, fromto)
            if d < AIR_CLEARANCE_M:
                return False
        return True

    def touches_pads(self, part: str) -> bool:
        return PADS in self.kinds_touching(part)
