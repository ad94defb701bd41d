"""Motion bounds of a collision scene's pairs: how fast each pair's distance can shrink
while the joints turn, and cheap lower bounds of the distances (covering spheres against
world boxes). The theory is in :mod:`cellrunner.planning.collision`'s docstring; the
conservative advancement that uses these bounds lives there too.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.planning.coal_shapes import world_aabb
from cellrunner.planning.motion_bounds import (
    cover_spheres,
    joint_reach,
    polytope_cover_spheres,
    support_points,
)

if TYPE_CHECKING:
    import coal

    from cellrunner.model.arm_geometry import ConvexPart
    from cellrunner.planning.kinematics import ArmKinematics


class BoundedObject(Protocol):
    """What the bounds read of one object of the scene
    (:class:`~cellrunner.planning.collision_scene.SceneObject`)."""

    @property
    def group(self) -> str: ...

    @property
    def body(self) -> int: ...

    @property
    def geometry(self) -> coal.CollisionGeometry: ...

    @property
    def placement(self) -> np.ndarray: ...

    @property
    def radius_m(self) -> float: ...

    @property
    def part(self) -> ConvexPart | None: ...


class PairBounds:
    """Per object and pair tables for the motion bound ``R[obj, j]`` and the lower bounds,
    built once per scene (``objects`` and checked ``pairs`` of a
    :class:`~cellrunner.planning.collision_scene.CollisionScene`)."""

    def __init__(
        self, kinematics: ArmKinematics, objects: Sequence[BoundedObject], pairs: np.ndarray
    ) -> None:
        self.kinematics = kinematics
        self._objects = objects
        self._pairs = pairs
        self._prepare_bounds()

    def _prepare_bounds(self) -> None:
        """Per-object data for the cheap lower bounds and the motion bound R[obj, j]."""
        model = self.kinematics.model
        n = len(self._objects)
        self._is_mover = np.array([o.group != "fixture" and o.body > 0 for o in self._objects])
        self._body = np.array([o.body for o in self._objects])
        self._center_local = np.zeros((n, 3))  # bounding sphere centre in the parent joint frame
        self._radius = np.zeros(n)
        self._reach = np.zeros((n, 6))  # R[obj, j]
        support: list[tuple[np.ndarray, float]] = []
        for k, obj in enumerate(self._objects):
            self._center_local[k] = obj.placement[:3, 3]
            self._radius[k] = obj.radius_m
            support.append(
                (obj.part.vertices_m, 0.0)
                if obj.part is not None
                else support_points(obj.geometry, obj.placement)
            )
            if self._is_mover[k]:
                self._reach[k] = joint_reach(model, obj.body, *support[k])
        # points of the moving objects, each with a pad, for per-segment radial extents:
        # a mesh part's covering spheres (a few, where its hull has about a hundred
        # vertices: the bound is looser by at most a sphere's overshoot and far cheaper),
        # a primitive's support points
        movers = np.flatnonzero(self._is_mover)
        self._movers = movers
        self._covers = {int(k): self._cover_spheres(self._objects[int(k)]) for k in movers}
        radial = [
            self._covers[int(k)]
            if self._objects[int(k)].part is not None
            else (support[k][0], np.full(len(support[k][0]), support[k][1]))
            for k in movers
        ]
        self._support_all = (
            np.concatenate([pts for pts, _ in radial]) if len(movers) else np.zeros((0, 3))
        )
        self._support_pad = (
            np.concatenate([pad for _, pad in radial]) + 1e-6 if len(movers) else np.zeros(0)
        )
        counts = [len(pts) for pts, _ in radial]
        self._support_start = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
        self._support_body = np.repeat(self._body[movers], counts)
        self._support_moved = (np.arange(1, 7)[None, :] <= self._support_body[:, None]).astype(
            float
        )
        # static objects: world AABBs (fixtures, base)
        self._aabb_lo = np.full((n, 3), np.nan)
        self._aabb_hi = np.full((n, 3), np.nan)
        for k, obj in enumerate(self._objects):
            if obj.group == "fixture" or obj.body == 0:
                T = (
                    obj.placement
                    if obj.group == "fixture"
                    else self.kinematics.T_world_base @ obj.placement
                )
                lo, hi = world_aabb(obj.geometry, T)
                self._aabb_lo[k], self._aabb_hi[k] = lo, hi
        a, b = self._pairs[:, 0], self._pairs[:, 1]
        a_moves = self._is_mover[a]
        # per pair: a moving object, the other one, and whether the other is static
        self._pair_mover = np.where(a_moves, a, b)
        self._pair_other = np.where(a_moves, b, a)
        self._pair_other_static = ~self._is_mover[self._pair_other]
        # motion bound per pair and joint: against a static object, the mover's own bound;
        # between two arm-carried objects, only the joints between their bodies move one
        # relative to the other (distances are the same in the lower body's frame)
        self._pair_high = self._pair_mover.copy()  # the object whose motion counts
        self._pair_joints = np.ones((len(self._pairs), 6))  # 1 for the joints that count
        for p, (m, o) in enumerate(zip(self._pair_mover, self._pair_other, strict=True)):
            if not self._pair_other_static[p]:
                low, high = (m, o) if self._body[m] <= self._body[o] else (o, m)
                self._pair_high[p] = high
                self._pair_joints[p] = np.arange(1, 7) > self._body[low]
        self.pair_reach = self._reach[self._pair_high] * self._pair_joints
        # row of each pair's counting object in the movers' support arrays
        self._pair_high_row = np.searchsorted(movers, self._pair_high)
        self._prepare_lower_bounds()

    @staticmethod
    def _cover_spheres(obj: BoundedObject) -> tuple[np.ndarray, np.ndarray]:
        """Spheres (centres in the parent joint frame, radii) whose union holds ``obj``."""
        if obj.part is not None:
            return polytope_cover_spheres(obj.part.vertices_m, obj.part.faces)
        return cover_spheres(obj.geometry, obj.placement)

    def _prepare_lower_bounds(self) -> None:
        """Covering spheres of the moving objects (grouped by object) and the static
        objects' world AABBs, for :meth:`_knot_lower_bounds`."""
        centers, radii, owner = [], [], []
        for row, k in enumerate(self._movers):
            c, r = self._covers[int(k)]
            centers.append(c)
            radii.append(r)
            owner += [row] * len(r)
        owner_arr = np.array(owner, dtype=int)
        self._sphere_local = np.concatenate(centers) if centers else np.zeros((0, 3))
        self._sphere_r = np.concatenate(radii) if radii else np.zeros(0)
        self._sphere_body = (
            self._body[self._movers][owner_arr] if len(owner_arr) else np.zeros(0, int)
        )
        self._sphere_start = np.searchsorted(owner_arr, np.arange(len(self._movers)))
        statics = np.flatnonzero(~self._is_mover)
        self._static_mid = tuple((0.5 * (self._aabb_lo[statics] + self._aabb_hi[statics])).T.copy())
        self._static_half = tuple(
            (0.5 * (self._aabb_hi[statics] - self._aabb_lo[statics])).T.copy()
        )
        static_col = {int(k): i for i, k in enumerate(statics)}
        mover_row = {int(k): i for i, k in enumerate(self._movers)}
        st = self._pair_other_static
        self._lb_static_pair = np.flatnonzero(st)
        self._lb_static_rows = np.array(
            [mover_row[int(m)] for m in self._pair_mover[st]], dtype=int
        )
        self._lb_static_cols = np.array(
            [static_col[int(o)] for o in self._pair_other[st]], dtype=int
        )
        self._lb_moving_pair = np.flatnonzero(~st)
        self._lb_moving_a = np.array([mover_row[int(m)] for m in self._pair_mover[~st]], dtype=int)
        self._lb_moving_b = np.array([mover_row[int(o)] for o in self._pair_other[~st]], dtype=int)
        # sphere combinations of the pairs of two moving objects, grouped by pair
        spheres_of = [
            np.arange(
                self._sphere_start[i],
                self._sphere_start[i + 1] if i + 1 < len(self._movers) else len(self._sphere_r),
            )
            for i in range(len(self._movers))
        ]
        combos = [
            (a, b, n)
            for n, (ra, rb) in enumerate(zip(self._lb_moving_a, self._lb_moving_b, strict=True))
            for a in spheres_of[ra]
            for b in spheres_of[rb]
        ]
        combo = np.array(combos, dtype=int).reshape(-1, 3)
        self._combo_a, self._combo_b = combo[:, 0], combo[:, 1]
        self._combo_r = self._sphere_r[combo[:, 0]] + self._sphere_r[combo[:, 1]]
        self._combo_start = np.searchsorted(combo[:, 2], np.arange(len(self._lb_moving_pair)))
        # all points transformed at every knot: support points, then sphere centres
        local = np.concatenate([self._support_all, self._sphere_local])
        self._point_local = np.hstack([local, np.ones((len(local), 1))])
        self._point_body = np.concatenate([self._support_body, self._sphere_body]).astype(int)
        # index of (point p, its body) in an array of every point in every joint frame
        self._point_pick = self._point_body * len(local) + np.arange(len(local))
        self._reach_movers = self._reach[self._movers]
        self._joint_placements = np.array(
            [self.kinematics.model.jointPlacements[j].homogeneous for j in range(1, 7)]
        )

    def motion_coefficients(self, dq_rad: np.ndarray) -> np.ndarray:
        """Per pair, the bound on how much its distance can shrink over the whole segment
        with joint displacement ``dq_rad`` (m), valid for any segment; see the module
        docstring."""
        return np.asarray(self.pair_reach @ np.abs(np.asarray(dq_rad, float)))

    def segment_bounds(self, q0_rad: np.ndarray, q1_rad: np.ndarray, pieces: int = 1) -> np.ndarray:
        """Per pair, a bound on how much its distance can shrink along the segment q0 -> q1
        split into ``pieces`` equal parts: (pieces, pairs) in m, one row per part. Each is
        :meth:`motion_coefficients` of the part with R[obj, j] replaced, when smaller, by a
        bound on the object's distance from axis j over that part only:

        at the part's ends the distances are measured (rho_a, rho_b, from the support points);
        in between they change at most at rate A_j = sum_(i>j) |dq_i| R[obj, i] per unit of
        the part (only the joints after j move the object relative to axis j), so
        r_j <= min(rho_a + t A_j, rho_b + (1 - t) A_j) <= (rho_a + rho_b + A_j) / 2 for t
        in [0, 1]."""
        return self.knots(q0_rad, q1_rad, pieces)[0]

    def knots(
        self, q0_rad: np.ndarray, q1_rad: np.ndarray, pieces: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`segment_bounds` (pieces, pairs) and, at the ``pieces + 1`` part ends,
        lower bounds of every pair's signed distance (pieces + 1, pairs), in m."""
        q0 = np.asarray(q0_rad, float)
        dq = (np.asarray(q1_rad, float) - q0) / pieces
        return self.polyline_bounds(q0 + np.arange(pieces + 1)[:, None] * dq)

    def polyline_bounds(self, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For the polyline through ``q_rad`` (knots x 6): per segment and pair, the bound
        on the distance shrink along the segment (:meth:`segment_bounds`), and per knot
        and pair, a lower bound of the signed distance (:meth:`_knot_lower_bounds`)."""
        q = np.asarray(q_rad, float)
        adq = np.abs(np.diff(q, axis=0))  # (pieces, 6)
        per_pair, lower = self.piece_bounds(q, adq)
        return np.einsum("kpj,kj->kp", per_pair, adq), lower

    def piece_bounds(self, q: np.ndarray, travel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For the pieces between the knots ``q`` (knots x 6), on each of which joint j turns
        by at most ``travel[:, j]`` in all (its |dq| on a straight piece, the sum of them on
        a polyline): per piece, pair and joint, a bound on how fast (m per rad of joint j)
        the pair's distance can shrink anywhere on the piece (pieces, pairs, 6); and per
        knot and pair, a lower bound of the signed distance (knots, pairs)."""
        knots = len(q)
        frames = self.joint_frames(q)  # (knots, 7, 4, 4)
        # every point in every joint frame by one product, then each in its own joint's,
        # coordinate-major (3, knots, points): sums over x, y, z are three whole-array adds
        every = frames[:, :, :3, :].reshape(-1, 4) @ self._point_local.T  # (knots * 7 * 3, P)
        pts = (
            every.reshape(knots, 7, 3, -1)
            .transpose(2, 0, 1, 3)
            .reshape(3, knots, -1)[:, :, self._point_pick]
        )
        n_support = len(self._support_all)
        # distances of the support points from the axes of the joints that move them:
        # |p - o|^2 - ((p - o) . z)^2, per joint axis (origin o, direction z)
        origins, axes = frames[:, None, 1:, :3, 3], frames[:, None, 1:, :3, 2]  # (knots, 1, 6, 3)
        along = square = 0.0
        for c in range(3):
            rel = pts[c, :, :n_support, None] - origins[..., c]  # (knots, support, 6)
            along = along + rel * axes[..., c]
            square = square + rel * rel
        square = square - along * along
        # + each point's pad and 1 um for rounding (far below STALL_M); joints that do not
        # move a point get its pad alone (their reach is 0)
        across = (np.sqrt(np.maximum(square, 0.0)) + self._support_pad[:, None]) * (
            self._support_moved
        )
        rho = np.maximum.reduceat(across, self._support_start, axis=1)
        reach = self._reach_movers  # (movers, 6)
        weighted = reach[None] * travel[:, None, :]  # (pieces, movers, 6)
        after = np.cumsum(weighted[:, :, ::-1], axis=2)[:, :, ::-1] - weighted  # A[:, :, j]
        lo, hi = rho[:-1], rho[1:]
        bound = np.minimum(reach, np.minimum(np.minimum(lo, hi) + after, 0.5 * (lo + hi + after)))
        per_pair = bound[:, self._pair_high_row] * self._pair_joints
        return per_pair, self._knot_lower_bounds(pts[:, :, n_support:])

    def joint_frames(self, q_rad: np.ndarray) -> np.ndarray:
        """World frames of joints 0..6 (0: the universe) at configurations ``q_rad`` (n x 6):
        (n, 7, 4, 4), the same as pinocchio's ``oMi``, computed for all n at once."""
        q = np.asarray(q_rad, float)
        n = len(q)
        rz = np.zeros((n, 6, 4, 4))
        c, s = np.cos(q), np.sin(q)
        rz[..., 0, 0] = c
        rz[..., 0, 1] = -s
        rz[..., 1, 0] = s
        rz[..., 1, 1] = c
        rz[..., 2, 2] = 1.0
        rz[..., 3, 3] = 1.0
        frames = np.empty((n, 7, 4, 4))
        frames[:, 0] = np.eye(4)
        for j in range(6):
            frames[:, j + 1] = frames[:, j] @ self._joint_placements[j] @ rz[:, j]
        return frames

    def _knot_lower_bounds(self, xyz: np.ndarray) -> np.ndarray:
        """(knots, pairs) lower bounds of the signed distances from the covering spheres
        (world centres ``xyz``, coordinate-major: (3, knots, spheres)) of the moving objects:
        the closest of an object's spheres to a static object's world AABB, or to another
        object's spheres (less 1 um for rounding); -inf where the covers overlap."""
        lb = np.empty((xyz.shape[1], len(self._pairs)))
        r = self._sphere_r
        if len(self._lb_static_pair):
            square = 0.0
            for c in range(3):
                gap = np.abs(xyz[c][:, :, None] - self._static_mid[c]) - self._static_half[c]
                np.maximum(gap, 0.0, out=gap)
                square = square + gap * gap
            dist = np.sqrt(square) - r[:, None]  # (knots, spheres, statics)
            per_object = np.minimum.reduceat(
                dist, self._sphere_start, axis=1
            )  # (knots, movers, statics)
            lb[:, self._lb_static_pair] = per_object[:, self._lb_static_rows, self._lb_static_cols]
        if len(self._lb_moving_pair):
            diff = xyz[:, :, self._combo_a] - xyz[:, :, self._combo_b]  # (3, knots, combos)
            diff *= diff
            dist = np.sqrt(diff[0] + diff[1] + diff[2]) - self._combo_r
            lb[:, self._lb_moving_pair] = np.minimum.reduceat(dist, self._combo_start, axis=1)
        # a bound at or below zero says the covers overlap, where the shapes may penetrate
        # deeper than any sphere radius: no bound at all there
        return np.where(lb > 0.0, lb - 1e-6, -np.inf)
