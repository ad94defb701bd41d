"""``check`` proves the watched zone is seen (SPEC section 12): the depth cameras of
``watch:`` that are fixed in the cell must together see at least ``MIN_ZONE_SEEN`` of the
zone's volume (sampled on a 10 x 10 x 10 grid: in front of a lens, inside its picture,
within its depth range). A camera on the flange moves with the arm and is not judged
here. A camera mounted with a slip (rolled to look at the ceiling) sees none of its zone:
the map would stay empty while the arm met what it was meant to see.

Why not every corner of the zone: a zone is drawn around the arm's work (down to the
table, out to the fence), wider than one overhead camera's cone near the floor; the
shipped watched cells see 66-74 % of their zones, and what they miss lies low at the
edges, where the arm does not reach over."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.failure import Failure, FailureKind

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell

#: the share of the watched zone's volume the fixed watch cameras must see together
MIN_ZONE_SEEN = 0.5


def watch_view_failures(cell: Cell) -> list[Failure]:
    """A failure when the fixed watch cameras together see less than MIN_ZONE_SEEN of the
    zone, naming each camera's share and the camera that sees least first."""
    watch = cell.watch
    if watch is None:
        return []
    from cellrunner.model.expand import camera_pose
    from cellrunner.planning.camera_view import seen_mask, zone_samples_m

    size = (watch.zone.box.size[0], watch.zone.box.size[1], watch.zone.box.size[2])
    samples = zone_samples_m(size, watch.zone.pose.matrix())
    fixed = [n for n in watch.cameras if n in cell.cameras and not cell.cameras[n].eye_in_hand]
    if not fixed:
        return []
    seen = np.zeros(len(samples), bool)
    shares: dict[str, float] = {}
    for name in fixed:
        camera = cell.cameras[name]
        rng = camera.depth.range_m if camera.depth is not None else None
        mask = seen_mask(camera, camera_pose(cell, name), samples, rng)
        shares[name] = float(mask.mean())
        seen |= mask
    share = float(seen.mean())
    if share >= MIN_ZONE_SEEN:
        return []
    worst = min(fixed, key=lambda n: shares[n])
    T = camera_pose(cell, worst)
    zone = " x ".join(f"{s:g}" for s in size)
    return [
        Failure(
            FailureKind.CAMERA_VIEW,
            f"the watch cameras see {share:.0%} of the {zone} m zone (at least "
            f"{MIN_ZONE_SEEN:.0%} must be seen): "
            + ", ".join(
                f"{n!r} sees {shares[n]:.0%}" for n in sorted(fixed, key=lambda n: shares[n])
            ),
            details=(
                f"camera {worst!r} looks along {_vector_text(T[:3, 2])} (world) from "
                f"{_vector_text(T[:3, 3], '.3f')} m (mount {cell.cameras[worst].mount}); the "
                f"zone's centre is at {_vector_text(watch.zone.pose.matrix()[:3, 3], '.3f')} m",
            ),
            fix="fix: turn or move the camera so the zone fills its picture (its pose's rpy: "
            "Z out of the lens, X right, Y down), or a zone the cameras see",
            step=f"watch camera {worst!r}",
        )
    ]


def _vector_text(v: np.ndarray, spec: str = "+.2f") -> str:
    return "[" + ", ".join(format(float(x), spec) for x in v) + "]"
