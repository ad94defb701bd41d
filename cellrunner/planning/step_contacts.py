"""Where the step planner stands (configuration, tool, carried part) and what may be
touched from there: the fixture a carried part is set down on or lifted off, the parts
waiting at their frames that the tool reaches around, and the contacts a force step or a
tight fit leaves for the next straight move (SPEC section 12). :class:`StepContacts` is the
base of :class:`~.step_planner.StepPlanner`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.body import LYING_KINDS, Body, BodyKind
from cellrunner.model.expand import Step
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.geometry import Placed
from cellrunner.planning.world import CellWorld

if TYPE_CHECKING:
    from cellrunner.planning.collision import CollisionModel, ContactAllowance


#: how far a carried part may press into the surface it is set down on or lifted off (m)
SET_DOWN_PRESS_M = 0.001
#: how far the tool may press into a waiting part it reaches around to grip (m)
GRIP_PRESS_M = 0.001


class StepContacts:
    """The planner's state, its collision model there, and the contacts it allows."""

    def __init__(self, world: CellWorld, q: np.ndarray, part: Placed | None) -> None:
        self.world, self.q, self.part = world, q, part
        self.allowances: tuple[ContactAllowance, ...] = ()
        #: where the first motion goes first, straight back, if it is a planned move
        #: (:mod:`.egress`): the job starts with the gripper down at a pick or place
        self.egress: tuple[np.ndarray, str] | None = None
        self.contact: tuple[
            ContactAllowance, ...
        ] = ()  # a force step's or tight fit's contacts, which the next straight move leaves

    def collision(
        self, allowances: tuple[ContactAllowance, ...] = (), step: Step | None = None
    ) -> CollisionModel:
        """The cell's model with the carried part, ``allowances``, and the clearance
        ``step`` keeps (its own ``clearance:``, SPEC section 12)."""
        from cellrunner.planning.tight_fit import step_clearance_m

        model = self.world.collision.carrying(self.part)
        model = model.allowing(*allowances) if allowances else model
        clearance = step_clearance_m(step)
        return model.keeping(clearance) if clearance is not None else model

    def _place_allowances(
        self,
        step: Step,
        T_goal: np.ndarray,
        named: tuple[ContactAllowance, ...] = (),
        ends_q: tuple[np.ndarray, np.ndarray | None] | None = None,
    ) -> tuple[ContactAllowance, ...]:
        """The carried part may touch the fixture it rests on where a straight move starts
        (lifting it off) or ends (setting it down), and only that fixture; and the fixtures
        the step names in ``contact:`` (``named``) anywhere along it. ``ends_q``: the
        line's start and end configurations, where they are not where the planner stands
        and the nearest branch of ``T_goal`` (an approach weighing a branch for the line
        after it)."""
        from cellrunner.planning.collision import STALL_M, ContactAllowance
        from cellrunner.planning.placed import beside_refusal

        if self.part is None or not step.is_line:
            return self.contact + named
        q_start, q_goal = ends_q if ends_q is not None else (self.q, self._try_ik(T_goal))
        # a force step's contact comes first: the part leaves it as deep as the step let it
        # go (the set-down rule below is for the surfaces it is lifted off or set down on)
        allowances: list[ContactAllowance] = [*self.contact, *named]
        for end, q in (("start", q_start), ("end", q_goal)):
            if q is None:
                continue
            model = self.collision(tuple(allowances), step)
            for _ in range(3):
                clearance = model.clearance(q)
                if (
                    clearance.distance_m >= clearance.required_m + STALL_M
                    or clearance.a.kind is not BodyKind.PART
                    or clearance.a.name != self.part.name
                    or not clearance.b.is_obstacle
                ):
                    break
                # valid is clear by STALL_M more than required (the verifier's rule): within
                # that, a part set down rests on what is under it, and keeps clear of the rest
                # (a hole's walls stay walls unless the step names them in contact:)
                if clearance.distance_m >= clearance.required_m and not self._under(
                    clearance.b.fixture_name, q
                ):
                    break
                if not self._under(clearance.b.fixture_name, q) and (
                    beside := beside_refusal(step, self.part.name, clearance, end)
                ):
                    raise InfeasibleError(beside)
                if clearance.distance_m < -SET_DOWN_PRESS_M:
                    depth_mm = -clearance.distance_m * 1000
                    reason = (
                        f"at its {end} the part '{self.part.name}' would be {depth_mm:.1f} mm inside "
                        f"{clearance.b} (setting a part down may press {SET_DOWN_PRESS_M * 1000:.0f} mm at most)"
                    )
                    # about ``step``, which may be the descend an approach looks ahead to
                    raise InfeasibleError(
                        Failure(
                            FailureKind.SUPPORT,
                            reason,
                            blockers=(Blocker(clearance.b, clearance.distance_m),),
                            fix=f"move the target up by {depth_mm - SET_DOWN_PRESS_M * 1000:.1f} mm or more",
                            step_index=step.index,
                            step=step.label,
                        )
                    )
                support = clearance.b.fixture_name
                allowances.append(ContactAllowance(support, "part", -SET_DOWN_PRESS_M))
                # the jaws around a short part come down to what it is set on (or lifted off)
                allowances.append(ContactAllowance(support, "tool", -GRIP_PRESS_M))
                model = self.collision(tuple(allowances), step)
        return tuple(allowances)

    def _under(self, name: str, q: np.ndarray) -> bool:
        """Whether fixture (or waiting part) ``name`` is what the carried part rests on at
        ``q``: a thin probe from the part's centre straight down, to the clearance below
        its lowest point, meets it (as :func:`~.support.check_support` finds a support; a
        hole's wall beside the part is not under it)."""
        from cellrunner.planning.collision import STALL_M
        from cellrunner.planning.support import distances, down_probe

        assert self.part is not None  # a part is being set down
        T_world_part = self.world.kinematics.T_world_tcp(q) @ self.part.T_parent_shape
        below_m = self.world.collision.clearance_m + STALL_M
        probe = down_probe(self.part, T_world_part, below_m)
        things = [t for t in (*self.world.fixtures, *self.world.waiting_parts) if t.name == name]
        return any(d <= STALL_M for d in distances(self.world, probe, things))

    def _waiting_touches(self, T_goal: np.ndarray) -> tuple[ContactAllowance, ...]:
        """A straight move's tool may touch the parts waiting at their frames that it is
        within clearance of where the line starts or ends: the jaws or cups reaching to a
        part to grip it, or leaving it (a retry's retreat); never the joint moves, whose
        sweep must keep clear of every waiting part (SPEC section 12). Around a short part
        the jaws may also come down to the fixture it rests on (as far as onto the part)."""
        from cellrunner.planning.collision import ContactAllowance

        if not self.world.waiting_parts:
            return ()
        model = self.collision()
        names: set[str] = set()
        supports: set[str] = set()
        gripped: set[str] = set()  # the part a grip here takes: the tool may reach into it
        for q in (self.q, self._try_ik(T_goal)):
            violations = model.violations(q) if q is not None else []
            touched = {
                v.b.fixture_name
                for v in violations
                if v.a.kind is BodyKind.TOOL and v.b.kind in LYING_KINDS
            }
            names |= touched
            held = self._waiting_at_tcp(q) if q is not None else set()
            gripped |= held & touched
            under = {f for name in held for f in self.world.waiting_supports.get(name, ())}
            supports |= {
                v.b.name
                for v in violations
                if v.a.kind is BodyKind.TOOL and v.b.kind is BodyKind.FIXTURE and v.b.name in under
            }
        return tuple(
            ContactAllowance(name, "tool", -1.0 if name in gripped else -GRIP_PRESS_M)
            for name in sorted(names)
        ) + tuple(ContactAllowance(f, "tool", -GRIP_PRESS_M) for f in sorted(supports))

    def _waiting_at_tcp(self, q: np.ndarray) -> set[str]:
        """The waiting parts a grip at ``q`` would take: those whose bounding sphere holds
        the TCP (centred between jaws, or the top face under the cups)."""
        from cellrunner.planning.coal_shapes import make_coal_shape

        p = self.world.kinematics.p_world_tcp(q)
        return {
            part.name
            for part in self.world.waiting_parts
            if np.linalg.norm(np.asarray(part.T_parent_shape)[:3, 3] - p)
            <= make_coal_shape(part.shape)[1]
        }

    def frame_at_tcp(self) -> str:
        """The frame of the part a grip here takes (:meth:`_waiting_at_tcp`), or ''."""
        names = {Body.fixture(name).name for name in self._waiting_at_tcp(self.q)}
        return next((p.at for p in self.world.loaded.cell.parts if p.name in names), "")

    def _try_ik(self, T: np.ndarray) -> np.ndarray | None:
        try:
            return np.asarray(self.world.kinematics.ik_nearest(T, self.q))
        except InfeasibleError:
            return None
