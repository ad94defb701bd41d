"""What a placed part rests on (issue 24: check approved a place in thin air, off the
pallet, which the twin then failed as the part fell).

At a place's release, the part must rest, within the cell's ``place_tolerance`` distance, on a
fixture, on a part waiting at its frame, or on a part an earlier slot of the same pattern
placed (a carton on the layer below): a thin probe from the part's centre straight down
(world -Z) to that distance below its lowest point must touch one of them, so that the
support is under the part's centre (a part half over a table's edge falls, even when its
edge touches the table).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.body import WAITING_PREFIX, Body, BodyKind
from cellrunner.model.failure import Blocker, Failure, FailureKind
from cellrunner.model.geometry import Box, Cylinder, Placed, Shape, Sphere
from cellrunner.planning.collision_scene import fixture_label

if TYPE_CHECKING:
    from cellrunner.model.step import Step
    from cellrunner.planning.world import CellWorld

#: a part this close to a support touches it (m)
TOUCH_M = 1e-4
#: a part let go this far above its support lands where it was put, and only the fall
#: beyond it counts against place_tolerance: the twin's rule (sim/places.PLACE_DROP_M, which
#: planning may not import; tests/planning/test_support.py keeps the two equal)
FORGIVEN_DROP_M = 0.01
#: radius of the probe under a part's centre (m)
PROBE_RADIUS_M = 0.001


def extent_below_m(shape: Shape, T_world_shape: np.ndarray) -> float:
    """How far the shape reaches below its origin along world -Z (m); a mesh counts as
    its bounding sphere."""
    z = np.asarray(T_world_shape, float)[2, :3]  # world Z in the shape's axes
    if isinstance(shape, Box):
        return float(np.abs(z) @ np.asarray(shape.size_m, float)) / 2
    if isinstance(shape, Cylinder):
        along = abs(float(z[2]))
        return (
            along * shape.length_m / 2
            + float(np.sqrt(max(0.0, 1 - along * along))) * shape.radius_m
        )
    if isinstance(shape, Sphere):
        return float(shape.radius_m)
    from cellrunner.planning.coal_shapes import make_coal_shape

    return make_coal_shape(shape)[1]


def check_support(
    world: CellWorld, step: Step, q_rad: np.ndarray, part: Placed, earlier_tcp: list[np.ndarray]
) -> None:
    """Raise InfeasibleError unless ``part`` (held in the TCP frame at ``q_rad``) rests on
    something within ``place_tolerance`` when ``step`` lets it go; ``earlier_tcp``: the
    TCP targets of the earlier slots of its pattern, each holding the same part."""
    drop_m = float(world.loaded.cell.place_tolerance.distance)
    T_world_part = world.kinematics.T_world_tcp(q_rad) @ part.T_parent_shape
    probe = down_probe(part, T_world_part, FORGIVEN_DROP_M + drop_m)
    supports = _supports(world, part.name)
    if min(distances(world, probe, supports), default=np.inf) <= TOUCH_M or _touches_earlier(
        part, probe, earlier_tcp
    ):
        return
    held = Placed(part.name, part.shape, T_world_part)
    # the nearest thing is among the fixtures and the parts earlier slots put down (the
    # carton 23 mm below, not the pallet 173 mm below it)
    earlier = [
        Placed(part.name, part.shape, np.asarray(T) @ part.T_parent_shape) for T in earlier_tcp
    ]
    gaps = distances(world, held, [*supports, *earlier])
    k = int(np.argmin(gaps)) if gaps else -1
    nearest: Body | None = None
    what = "nothing"
    if 0 <= k < len(supports):
        nearest = fixture_label(supports[k].name)
        what = str(nearest)
    elif k >= len(supports):
        nearest = Body(BodyKind.PART, part.name)
        what = f"the {nearest} an earlier slot put down"
    gap_mm = gaps[k] * 1000 if k >= 0 else float("inf")
    raise InfeasibleError(
        Failure(
            FailureKind.SUPPORT,
            f"the part '{part.name}' would be let go with nothing under it within "
            f"place_tolerance {drop_m * 1000:.0f} mm (the nearest thing is "
            f"{what}, {gap_mm:.1f} mm away): it falls",
            blockers=(Blocker(nearest, gaps[k]),) if nearest is not None else (),
            fix="fix: lower the place frame onto its support, or place it where a fixture or "
            "an earlier part holds it",
            step_index=step.index,
            step=step.label,
        )
    )


def down_probe(part: Placed, T_world_part: np.ndarray, below_m: float) -> Placed:
    """A thin probe from the part's centre straight down (world -Z) to ``below_m`` below
    its lowest point: what it meets is under the part's centre."""
    length_m = extent_below_m(part.shape, T_world_part) + below_m
    T_world_probe = np.eye(4)
    T_world_probe[:3, 3] = np.asarray(T_world_part)[:3, 3] - (0.0, 0.0, length_m / 2)
    return Placed(part.name, Cylinder(PROBE_RADIUS_M, length_m), T_world_probe)


def _supports(world: CellWorld, carried: str) -> list[Placed]:
    """What a part may rest on: the fixtures and the waiting parts (not its own place)."""
    own = WAITING_PREFIX + carried
    return [*world.fixtures, *(p for p in world.waiting_parts if p.name != own)]


def distances(world: CellWorld, shape: Placed, others: list[Placed]) -> list[float]:
    """Signed distances (m) of ``shape`` to each of ``others``, all placed in the world."""
    import coal

    def transform(T: np.ndarray) -> coal.Transform3s:
        return coal.Transform3s(np.asarray(T[:3, :3]), np.asarray(T[:3, 3]))

    scene = world.collision
    here = transform(shape.T_parent_shape)
    return [
        float(
            coal.distance(
                scene.geometry_of(shape.shape),
                here,
                scene.geometry_of(other.shape),
                transform(other.T_parent_shape),
                coal.DistanceRequest(),
                coal.DistanceResult(),
            )
        )
        for other in others
    ]


def _touches_earlier(part: Placed, probe: Placed, earlier_tcp: list[np.ndarray]) -> bool:
    """Whether ``probe`` (placed in the world) touches the part an earlier slot placed at
    each of ``earlier_tcp`` (TCP targets holding ``part`` as now)."""
    if not earlier_tcp:
        return False
    import coal

    from cellrunner.planning.coal_shapes import make_coal_shape

    shape, _ = make_coal_shape(part.shape)
    probe_shape, _ = make_coal_shape(probe.shape)

    def transform(T: np.ndarray) -> coal.Transform3s:
        return coal.Transform3s(np.asarray(T[:3, :3]), np.asarray(T[:3, 3]))

    here = transform(probe.T_parent_shape)
    for T_tcp in earlier_tcp:
        there = transform(np.asarray(T_tcp) @ part.T_parent_shape)
        result = coal.DistanceResult()
        if (
            coal.distance(probe_shape, here, shape, there, coal.DistanceRequest(), result)
            <= TOUCH_M
        ):
            return True
    return False
