"""Press fits in the twin (issue 33): a part pressed into a fit the task declares
(``insert: {force: {min, max}, contact: [...]}``) passes into its fixtures as far as the
fit allows, against the fit's force.

The cell file gives no materials, and a press fit's force is what its materials make of
the interference: the twin cannot compute it. So it presses a declared fit at the force in
the middle of the declared window (:func:`fit_force_N`), and what rehearsal proves is the
rest: the part's overlap with the fit's fixtures stays within the fit's
(:data:`cellrunner.planning.insert_fit.PRESS_FIT_MAX_M`, the rule ``check`` applies, else it
jams on them), the insert builds up its ``force.min`` only where the part really overlaps
its fixtures (a loose part goes in without it and fails), and the motion and the force
step's logic. Only the arm measures the real fit.

How: the fit's fixtures are built with a collision bit of their own
(:data:`.mjcf_attrs.PRESS`). Once a part comes within :data:`NEAR_M` of them (gripped, or
left in the fit), it stops colliding with them (it clears that bit of its conaffinity) and
the fit is judged geometrically each period (MuJoCo's ``mj_geomDistance``): overlapping
them, the part's translations meet a dry friction of the fit's force (MuJoCo's
``frictionloss`` on its free joint's sliding axes, an implicit constraint that the wrist
feels through the grip, and that holds a part let go in the fit where it was pressed);
overlapping them by more than the fit allows (``check``'s limit and the
:data:`PLACEMENT_TOLERANCE_M` a real arm's part is off its planned place), it collides with
them again: their contacts are rigid (:mod:`.rigid_contacts`) and it jams, as in a hole
with no press fit.
The look-ahead does not run while a part is in or near a fit (:meth:`PressFits.engaged`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from cellrunner.sim.mjcf_attrs import PRESS

#: a part this close to a fit's fixtures (m) stops colliding with them and is judged
NEAR_M = 0.005
#: how far off its planned place a part may be pressed into its fit (m), beyond the
#: interference ``check`` allows: the grip and the arm put a part up to 0.15 mm off centre
#: (measured on generated press fits), which a real fit absorbs as the part centres itself
#: in it; a part that lands on a rim is far past it
PLACEMENT_TOLERANCE_M = 1e-4
#: the rotational friction of a part in its fit, per N of the fit's force (N m / N)
TORSION_ARM_M = 0.01


def fit_force_N(force_min_N: float, force_max_N: float) -> float:
    """The force the twin's fit takes to press (N): the middle of the declared window."""
    return 0.5 * (force_min_N + force_max_N)


def press_fit_forces(tasks: Iterable[Any]) -> tuple[tuple[str, float], ...]:
    """(fixture, the fit's force N) for each fixture named in ``contact:`` by an insert of
    ``tasks`` (loaded tasks) that declares a press fit (``force: {min, max}``); the first
    insert naming a fixture sets its force."""
    forces: dict[str, float] = {}
    for task in tasks:
        for spec in task.steps:
            force = getattr(spec.args, "force", None)
            low = getattr(force, "min", None)
            if spec.kind != "insert" or low is None:
                continue
            for name in spec.args.contact or ():
                forces.setdefault(name, fit_force_N(float(low), float(force.max)))  # type: ignore[union-attr]
    return tuple(forces.items())


class PressFits:
    """The press fits of one built SimWorld (constructed after its model is compiled).
    ``inside``: the parts in or near a fit (colliding no more with its fixtures);
    ``jammed``: those pressed past what a fit allows (colliding again)."""

    def __init__(self, world: Any) -> None:
        from cellrunner.planning.insert_fit import PRESS_FIT_MAX_M

        self.world = world
        m = world.model
        self._mj = world.mujoco
        self.max_overlap_m = PRESS_FIT_MAX_M + PLACEMENT_TOLERANCE_M
        force = dict(world.description.press_fits)
        #: fixture geom -> the fit's force (N)
        self.geom_force_N = {
            g: force[name.split(":")[1]]
            for g in range(m.ngeom)
            if (name := m.geom(g).name).startswith("fixture:") and name.split(":")[1] in force
        }
        self._part_geom = {p: int(g) for p, g in world.ids.part_geom.items()}
        self._dofs = {
            p: int(m.jnt_dofadr[m.body_jntadr[b]]) for p, b in world.ids.part_bodies.items()
        }
        self._fromto = np.zeros(6)
        self.inside: set[str] = set()
        self.jammed: set[str] = set()

    def engaged(self) -> bool:
        """Whether a part is in or near a fit (the look-ahead steps aside)."""
        return bool(self.inside)

    def update(self, gripped: frozenset[str]) -> None:
        """After a period's physics: judge the gripped parts and those in a fit."""
        for part in gripped | self.inside:
            self._judge(part)

    def _judge(self, part: str) -> None:
        overlap_m, force_N = self._overlap(part)
        if overlap_m is None:  # clear of every fit
            self._rigid(part)
            self.jammed.discard(part)
            return
        if part in self.jammed:
            return
        if overlap_m > self.max_overlap_m:  # past what a fit allows: rigid again, it jams
            self._rigid(part)
            self.jammed.add(part)
            return
        self.inside.add(part)
        self._collide(part, False)
        self._friction(part, force_N if overlap_m > 0.0 else 0.0)

    def _overlap(self, part: str) -> tuple[float | None, float]:
        """The part's deepest overlap with a fit's fixtures (m, negative: the gap) and that
        fit's force (N); (None, 0) when it is NEAR_M or more from all of them."""
        w, g = self.world, self._part_geom[part]
        deepest: float | None = None
        force_N = 0.0
        for fixture, f_N in self.geom_force_N.items():
            d = self._mj.mj_geomDistance(w.model, w.data, g, fixture, NEAR_M, self._fromto)
            if d < NEAR_M and (deepest is None or -d > deepest):
                deepest, force_N = -float(d), f_N
        return deepest, force_N

    def _rigid(self, part: str) -> None:
        """Part ``part`` out of every fit: it collides with the fits' fixtures again, free
        of their friction."""
        self._collide(part, True)
        self._friction(part, 0.0)
        self.inside.discard(part)

    def _collide(self, part: str, on: bool) -> None:
        m, g = self.world.model, self._part_geom[part]
        bits = int(m.geom_conaffinity[g])
        m.geom_conaffinity[g] = bits | PRESS if on else bits & ~PRESS

    def _friction(self, part: str, force_N: float) -> None:
        m, dof = self.world.model, self._dofs[part]
        m.dof_frictionloss[dof : dof + 3] = force_N
        m.dof_frictionloss[dof + 3 : dof + 6] = force_N * TORSION_ARM_M
