"""Faults the twin makes physically happen (SPEC section 5, robot side): what the engine
must notice through the jaw sensor and the wrist, never through a flag.

- ``grip_miss``: the part at the gripper (the one nearest its pads or cups, whatever its
  size) is moved away as the jaws start to close, or suction comes on, far enough that
  the gripper closes on nothing;
- ``part_slip``: once a gripped part is in the air, the pads lose their grip on it (their
  friction drops until they hold a fraction of its weight) and it falls; the friction
  comes back once it left the fingers (``SLIP_CLEAR_M`` clear of both pads: a part
  falling between them may lose their contact for a period, and with their friction back
  they caught it again, 33 mm down).
"""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cellrunner.sim.wrist import GRAVITY_MPS2

if TYPE_CHECKING:
    from cellrunner.sim.contacts import ContactMonitor
    from cellrunner.sim.description import TwinDescription
    from cellrunner.sim.model_ids import ModelIds

SLIP_HOLD_FRACTION = 0.25  # a slipping grip holds only this fraction of the part's weight
#: a slipping part has left the fingers when this far from both pads (m)
SLIP_CLEAR_M = 0.005
GRIP_MISS_MOVE_M = 0.15  # how far grip_miss moves the part at least, towards the robot base
GRIP_MISS_CLEAR_M = 0.02  # and the gap it leaves between the part and the gripper


class Fault(enum.StrEnum):
    """Faults the twin can make physically happen (SPEC section 5, robot side)."""

    GRIP_MISS = "grip_miss"  # the part is moved away when the jaws start to close
    PART_SLIP = "part_slip"  # a gripped part loses its grip once in the air, and falls
    PROTECTIVE_STOP = "protective_stop"
    ESTOP = "estop"
    ROBOT_DISCONNECT = "robot_disconnect"  # handled by the backend (connection lost)

    @classmethod
    def parse(cls, name: str | Fault) -> Fault:
        try:
            return cls(name)
        except ValueError:
            known = ", ".join(f.value for f in cls)
            raise ValueError(f"unknown fault {name!r}; known: {known}") from None


class FaultWorld(Protocol):
    """What the grip faults act on in the twin (:class:`~cellrunner.sim.world.SimWorld`)."""

    description: TwinDescription
    model: Any
    data: Any
    contacts: ContactMonitor

    @property
    def mujoco(self) -> Any: ...

    @property
    def ids(self) -> ModelIds: ...


class GripFaults:
    """grip_miss and part_slip of one built :class:`SimWorld` (the jaws'; the cups keep
    their own, and use :meth:`move_part_away`)."""

    def __init__(self, world: FaultWorld) -> None:
        self.world = world
        self.grip_miss_armed = False
        self.slip_armed = False
        self.slipping: set[str] = set()

    @property
    def active(self) -> bool:
        """Whether :meth:`update` has anything to do this period."""
        return self.slip_armed or bool(self.slipping)

    def arm_slip(self, gripped: frozenset[str]) -> None:
        """Fires once a gripped part is in the air (at once if one is)."""
        self.slip_armed = True
        self._maybe_slip({p for p in gripped if self.world.contacts.in_air(p)})

    def jaws_closing(self) -> None:
        """The jaws start to close: an armed grip_miss moves the part away now."""
        if self.grip_miss_armed:
            self.grip_miss_armed = False
            g = self.world.description.gripper
            assert g is not None  # jaws close only where there is a jaw gripper
            self.move_part_away(list(self.world.ids.pad_geoms), g.stroke_m / 2 + 0.02)

    def update(self, gripped: frozenset[str]) -> None:
        """After the physics step: slip an armed part in the air, restore the friction of
        parts that left the fingers."""
        w, ids = self.world, self.world.ids
        if self.slip_armed:
            self._maybe_slip({p for p in gripped if w.contacts.in_air(p)})
        for name in list(self.slipping):
            if not w.contacts.touches_pads(name) and self._clear_of_pads(name):
                w.model.geom_friction[ids.part_geom[name]] = ids.part_friction[name]
                self.slipping.discard(name)
        if not self.slipping and ids.pad_geoms[0] >= 0:
            w.model.geom_friction[list(ids.pad_geoms)] = ids.pad_friction

    def _clear_of_pads(self, name: str) -> bool:
        """Whether part ``name`` is ``SLIP_CLEAR_M`` clear of both pads."""
        w = self.world
        g = w.ids.part_geom[name]
        fromto = np.zeros(6)
        return all(
            w.mujoco.mj_geomDistance(w.model, w.data, g, int(pad), SLIP_CLEAR_M, fromto)
            >= SLIP_CLEAR_M
            for pad in w.ids.pad_geoms
            if int(pad) >= 0
        )

    def _maybe_slip(self, candidates: set[str]) -> None:
        if not candidates:
            return
        self.slip_armed = False
        w, ids = self.world, self.world.ids
        g = w.description.gripper
        assert g is not None
        for name in candidates:
            self.slipping.add(name)
            # friction such that the two pads hold only a fraction of the weight
            weight = w.model.body_mass[ids.part_bodies[name]] * GRAVITY_MPS2
            mu = SLIP_HOLD_FRACTION * weight / (2.0 * g.grip_force_N)
            w.model.geom_friction[ids.part_geom[name], 0] = mu
            w.model.geom_friction[list(ids.pad_geoms), 0] = mu

    def move_part_away(self, grip_geoms: list[int], reach_m: float) -> None:
        """grip_miss: the part nearest ``grip_geoms`` (the pads or the cups), within
        ``reach_m`` of one, is moved towards the robot base until it is clear of the
        gripper: ``GRIP_MISS_MOVE_M``, or its own reach plus the gripper's (a 200 mm
        carton under four cups moves farther than a 50 mm cube between the jaws)."""
        w = self.world
        ids, data, m = w.ids, w.data, w.model
        best = self._part_at(grip_geoms, reach_m)
        if best is None:
            return
        tcp = data.site_xpos[ids.tcp_site]
        grip_reach = max(
            float(np.linalg.norm(data.geom_xpos[g][:2] - tcp[:2])) + float(m.geom_rbound[g])
            for g in grip_geoms
        )
        part_reach = float(m.geom_rbound[ids.part_geom[best]])
        move_m = max(GRIP_MISS_MOVE_M, grip_reach + part_reach + GRIP_MISS_CLEAR_M)
        adr = ids.part_qpos[best]
        base_xy = w.description.T_world_base[:2, 3]
        direction = base_xy - data.qpos[adr : adr + 2]
        norm = float(np.linalg.norm(direction))
        direction = direction / norm if norm > 1e-6 else np.array([-1.0, 0.0])
        data.qpos[adr : adr + 2] += move_m * direction
        data.qvel[m.jnt_dofadr[m.joint(f"part:{best}").id] + np.arange(6)] = 0.0
        w.mujoco.mj_forward(m, data)

    def _part_at(self, grip_geoms: list[int], reach_m: float) -> str | None:
        """The part whose surface is nearest one of ``grip_geoms``, within ``reach_m``."""
        w = self.world
        fromto = np.zeros(6)
        best, best_d = None, reach_m
        for name, geom in w.ids.part_geom.items():
            for g in grip_geoms:
                d = w.mujoco.mj_geomDistance(w.model, w.data, g, geom, best_d, fromto)
                if d < best_d:
                    best, best_d = name, d
        return best


def inject(world: Any, fault: str | Fault) -> None:
    """Make ``fault`` happen physically in ``world`` (a built SimWorld; see
    :meth:`~cellrunner.sim.world.SimWorld.inject_fault`)."""
    from cellrunner.sim.safety import StopReason

    f = Fault.parse(fault)
    if f in (Fault.GRIP_MISS, Fault.PART_SLIP) and world.vacuum is not None:
        setattr(world.vacuum, "grip_miss_armed" if f is Fault.GRIP_MISS else "slip_armed", True)
    elif f is Fault.GRIP_MISS:
        world.grip_faults.grip_miss_armed = True
    elif f is Fault.PART_SLIP:
        world.grip_faults.arm_slip(world._gripped)  # fires once a gripped part is in the air
    elif f is Fault.PROTECTIVE_STOP:
        world.raise_protective_stop(StopReason.INJECTED)
    elif f is Fault.ESTOP:
        world.press_estop()
    else:
        raise ValueError(f"fault {f.value!r} is handled by the backend, not the physics")
