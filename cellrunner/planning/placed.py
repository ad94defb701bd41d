"""The parts a job finds or leaves set down: obstacles to every step after them, supports
to a place onto them (issue 33).

- A place's release leaves its part where it was let go (``placed:NAME@STEP``; the
  release checks that it rests there, :mod:`.support`).
- The earlier slots of a place's pattern hold the parts earlier jobs put there
  (``placed:NAME@slotK``): the carton on the layer below, the one beside it. The twin
  spawns them (sim/feed); check plans the whole job around them, from its start, and a
  joint move that fails verification by a hair against one is planned again with the
  planner's margin (:func:`~.task_plan._plan_with_margin`). The jaw pads, which check
  models fully open, are not checked against them: while a part is carried they are
  closed on it, and the demo's pads, open, would reach 9.5 mm into the block beside
  their slot (opening at the release, they may nudge it: the twin's jobs end 0).

The planner's world carries them (:meth:`CellWorld.with_placed
<cellrunner.planning.world.CellWorld.with_placed>`) as parts lying in the cell, beside the
waiting ones: a grip's jaws may leave one they let go, a later place may come down onto
one, and every other move keeps the cell's clearance from them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.body import PLACED_PREFIX, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.geometry import Placed, Shape
from cellrunner.model.step import StepKind

if TYPE_CHECKING:
    from cellrunner.model.step import Step
    from cellrunner.planning.collision_scene import Clearance
    from cellrunner.planning.world import CellWorld

#: an earlier slot whose part lies this close to a part of the cell file is that part (m)
SAME_PLACE_M = 0.01


def placed_part(part: Placed, T_world_part: np.ndarray, where: str) -> Placed:
    """The carried ``part`` set down at ``T_world_part``, named ``placed:NAME@WHERE``."""
    return Placed(f"{PLACED_PREFIX}{part.name}@{where}", part.shape, T_world_part)


def earlier_slot_parts(world: CellWorld, steps: list[Step]) -> tuple[Placed, ...]:
    """The parts on the earlier slots of each patterned place in ``steps``, where the
    grip before that place holds its part: what earlier jobs left there. A slot where a
    part of the cell file (or another slot's part) already lies is left to that part."""
    out: list[Placed] = []
    lying = [np.asarray(p.T_parent_shape)[:3, 3] for p in world.waiting_parts]
    T_last: np.ndarray | None = None  # where the last move to a frame put the TCP
    part: Placed | None = None  # what the last grip holds, in the TCP frame
    for step in steps:
        if step.is_motion and step.T_world_tcp is not None:
            T_last = np.asarray(step.T_world_tcp, float)
        elif step.kind == StepKind.GRIP and T_last is not None:
            frame = step.extra.get("part_at")
            pose = step.extra.get("part_pose")
            part = world.part_at(frame, T_last, pose) if isinstance(frame, str) else None
        elif step.kind == StepKind.RELEASE:
            for k, T_world_tcp in enumerate(step.extra.get("earlier_slots", [])):
                if part is None:
                    break
                T_world_part = np.asarray(T_world_tcp, float) @ part.T_parent_shape
                p = T_world_part[:3, 3]
                if any(float(np.linalg.norm(p - q)) < SAME_PLACE_M for q in lying):
                    continue
                lying.append(p)
                out.append(placed_part(part, T_world_part, f"slot{k}"))
            part = None
    return tuple(out)


def found_parts(world: CellWorld, steps: list[Step]) -> tuple[Placed, ...]:
    """The parts an align finds (s90344): a part off its frame on purpose (``offset``)
    lies where a camera finds it, which check does not know, so it is no waiting part of
    the cell (:attr:`CellWorld.waiting_parts`). But it lies within the align's
    ``max_correction`` of its frame, or the align fails: an obstacle there, grown by that
    box, to every move until it is carried (a wall-mounted UR16e's move to the look pose
    swept its forearm through one, 311 N in the twin, that check never saw). Named as a
    waiting part (``part:NAME``), so that the grip's jaws may reach into it and the job
    carries it away."""
    from cellrunner.model.align import aligned_frame
    from cellrunner.model.body import WAITING_PREFIX

    cell = world.loaded.cell
    grown: dict[str, Placed] = {}
    for i, step in enumerate(steps):
        if step.kind != StepKind.ALIGN:
            continue
        frame = aligned_frame(steps, i)
        box = step.args.max_correction
        for part in cell.parts:
            if part.at != frame or part.offset is None or frame not in cell.frames:
                continue
            shape, T = world.at_its_frame(part)
            big = _grown(shape, np.asarray(box.xyz, float), float(np.radians(box.rpy[2])))
            old = grown.get(part.name)
            if old is None or _volume(big) > _volume(old.shape):
                grown[part.name] = Placed(WAITING_PREFIX + part.name, big, T)
    return tuple(grown.values())


def _grown(shape: Shape, xyz_m: np.ndarray, yaw_rad: float) -> Shape:
    """``shape`` grown to hold itself shifted by up to ``xyz_m`` (each axis, both ways)
    and turned by up to ``yaw_rad`` about its Z (a mesh as it is)."""
    dx, dy, dz = np.abs(xyz_m)
    turn = abs(np.sin(yaw_rad))
    if isinstance(shape, geometry.Box):
        hx, hy, hz = (v / 2 for v in shape.size_m)
        return geometry.Box((2 * (hx + dx + hy * turn), 2 * (hy + dy + hx * turn), 2 * (hz + dz)))
    if isinstance(shape, geometry.Cylinder):
        return geometry.Cylinder(shape.radius_m + max(dx, dy), shape.length_m + 2 * dz)
    if isinstance(shape, geometry.Sphere):
        return geometry.Sphere(shape.radius_m + float(np.linalg.norm(xyz_m)))
    return shape


def _volume(shape: Shape) -> float:
    if isinstance(shape, geometry.Box):
        return float(np.prod(shape.size_m))
    if isinstance(shape, geometry.Cylinder):
        return float(np.pi * shape.radius_m**2 * shape.length_m)
    if isinstance(shape, geometry.Sphere):
        return float(4 / 3 * np.pi * shape.radius_m**3)
    return 0.0


def beside_refusal(step: Step, part_name: str, clearance: Clearance, end: str) -> Failure | None:
    """A part set down within the clearance of a part lying beside it (not under it: the
    earlier slot's carton next to this slot, a column pitch no wider than the carton) is
    refused, naming that part and the distance; None when ``clearance`` is not such a pair.
    Fixtures beside the part keep the set-down rule (a bin's wall, a shelf's back)."""
    if clearance.b.kind is not BodyKind.PLACED_PART or clearance.distance_m >= clearance.required_m:
        return None
    reason = (
        f"at its {end} the part '{part_name}' would be {abs(clearance.distance_m) * 1000:.1f} mm "
        f"{'inside' if clearance.distance_m < -5e-5 else 'from'} {clearance.b} beside it (it must "
        f"keep {clearance.required_m * 1000:.1f} mm)"
    )
    return Failure(
        FailureKind.COLLISION,
        reason,
        blockers=(Blocker(clearance.b, clearance.distance_m),),
        fix="a wider pattern pitch (the part's width plus the cell's clearance), or move the target",
        step_index=step.index,
        step=step.label,
    )
