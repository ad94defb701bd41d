"""Blending the corners of a group of motions timed as one: a quadratic Bezier arc in joint
space, collision-checked, the part end of a straight step kept straight (:func:`_blend`)."""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.planning.step_plan import _Motion
from cellrunner.planning.world import CellWorld

if TYPE_CHECKING:
    from cellrunner.planning.kinematics import ArmKinematics


#: blends where a joint move meets a straight step (:func:`_blend`): at most this share
#: of the straight step's line and this distance (m) from the corner, like the radii a
#: UR integrator sets (bench/polyscope.py uses the same)
LINEAR_BLEND_FRACTION = 0.4
BLEND_RADIUS_MAX_M = 0.05
#: between two joint moves of different steps: this share of each adjacent edge
CORNER_FRACTION = 0.35
BLEND_POINTS = 24


def _blend(world: CellWorld, group: list[_Motion]) -> list[_Motion]:
    """The group with each corner between two motions rounded by a quadratic Bezier arc in
    joint space, as a PolyScope blend radius does: it leaves the first motion at A and
    joins the second at B, with the corner as control point. On a straight step, A (or B)
    is at most ``LINEAR_BLEND_FRACTION`` of its line and ``BLEND_RADIUS_MAX_M`` from the
    corner, so the part end of a descend, lift or retreat stays straight; on a joint move,
    as far along its edge (joint-space distance) as the straight side, at most half of the
    edge. The arc belongs to the joint move and is checked with its collision model; the
    straight step keeps its (shorter) line, verified straight. Corners no arc clears stay
    sharp."""
    out = [
        _Motion(m.row, np.asarray(m.waypoints, float), m.limits, m.line_m, m.collision, m.world)
        for m in group
    ]
    kin = group[0].world.kinematics  # the tool mounted for this group
    for a, b in itertools.pairwise(out):
        a_line, b_line = a.line_m is not None, b.line_m is not None
        if (a_line and b_line) or _still(a.waypoints) or _still(b.waypoints):
            continue
        joint = b if a_line else a
        for shrink in (1.0, 0.5, 0.25):
            blended = _corner_arc(kin, a, b, shrink)
            if blended is not None and joint.collision.check_path(blended[2]).ok:
                a.waypoints, b.waypoints = blended[0], blended[1]
                if a.line_m is not None:
                    a.line_m = (a.line_m[0], kin.p_world_tcp(a.waypoints[-1]))
                if b.line_m is not None:
                    b.line_m = (kin.p_world_tcp(b.waypoints[0]), b.line_m[1])
                break
    return out


def _still(q_rad: np.ndarray) -> bool:
    return float(np.abs(q_rad - q_rad[0]).max()) < 1e-9


def _corner_arc(
    kin: ArmKinematics, a: _Motion, b: _Motion, shrink: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(a's waypoints, b's waypoints, the arc) with the corner between them rounded
    (:func:`_blend`); the arc is the start of the joint move (or its end when b is the
    straight one). None when a side is too short to blend."""
    corner = a.waypoints[-1]
    t = np.linspace(0.0, 1.0, BLEND_POINTS)[:, None]

    def straight_point(line_q: np.ndarray, from_end: bool) -> int | None:
        p = kin.p_world_tcp_many(line_q)
        length = float(np.linalg.norm(p[-1] - p[0]))
        radius = min(LINEAR_BLEND_FRACTION * length, BLEND_RADIUS_MAX_M) * shrink
        d = np.linalg.norm(p - (p[-1] if from_end else p[0]), axis=1)
        inside = np.nonzero(d < radius)[0]
        if radius <= 1e-4 or len(inside) == 0:
            return None
        k = inside[0] if from_end else inside[-1]  # the farthest sample within the radius
        return int(k) if 0 < k < len(line_q) - 1 else None

    def rounded(start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """The quadratic Bezier arc from ``start`` through the corner's pull to ``end``."""
        return np.asarray((1 - t) ** 2 * start + 2 * (1 - t) * t * corner + t**2 * end)

    def along(edge_from: np.ndarray, edge_to: np.ndarray, distance: float) -> np.ndarray:
        edge = edge_to - edge_from
        length = float(np.linalg.norm(edge))
        return np.asarray(edge_from + edge * min(distance / max(length, 1e-12), 0.5))

    if a.line_m is not None:  # straight -> joint
        if len(b.waypoints) < 2:
            return None
        k = straight_point(a.waypoints, from_end=True)
        if k is None:
            return None
        start = a.waypoints[k]
        end = along(corner, b.waypoints[1], float(np.linalg.norm(corner - start)))
        arc = rounded(start, end)
        return a.waypoints[: k + 1], np.vstack([arc, b.waypoints[1:]]), arc
    if b.line_m is not None:  # joint -> straight
        if len(a.waypoints) < 2:
            return None
        k = straight_point(b.waypoints, from_end=False)
        if k is None:
            return None
        end = b.waypoints[k]
        start = along(corner, a.waypoints[-2], float(np.linalg.norm(end - corner)))
        arc = rounded(start, end)
        return np.vstack([a.waypoints[:-1], arc]), b.waypoints[k:], arc
    if len(a.waypoints) < 2 or len(b.waypoints) < 2:  # joint -> joint
        return None
    f = CORNER_FRACTION * shrink
    start = along(corner, a.waypoints[-2], f * float(np.linalg.norm(a.waypoints[-2] - corner)))
    end = along(corner, b.waypoints[1], f * float(np.linalg.norm(b.waypoints[1] - corner)))
    arc = rounded(start, end)
    return np.vstack([a.waypoints[:-1], arc]), np.vstack([arc[-1:], b.waypoints[1:]]), arc
