"""Collision model of the arm, its tool, a carried part and the cell's fixtures (coal):
the scene (:mod:`.collision_scene`: objects, checked pairs, clearances, state queries), the
motion bounds (:mod:`.collision_bounds`), and here the derived models (a part carried,
contacts allowed) and the motion checks, which prove whole segments and paths.

Objects and frames:

- arm: the convex parts of :func:`cellrunner.model.arm_geometry.arm_geometry` (derived from
  Universal Robots' collision meshes, which they contain), on pinocchio joint i (body 0 =
  base, fixed at the mount). Names: the links', ``base``, ``shoulder``, ``upper_arm``,
  ``forearm``, ``wrist_1``, ``wrist_2``, ``wrist_3``. A model without derived geometry is
  refused (:class:`InfeasibleError`), never guessed.
- tool: shapes placed in the flange frame (``Placed.T_parent_shape`` = ``T_flange_shape``).
- part: the carried part, placed in the TCP frame (``T_tcp_shape``); see
  :meth:`CollisionModel.carrying`.
- fixtures: shapes placed in the world (``T_world_shape``): box, cylinder, sphere, STL mesh.

Pairs never checked (they touch by construction or are rigidly joined): arm parts that the
derivation proved apart by more than the clearance over the joints' ranges, or that are the
joint between adjacent links (:meth:`ArmGeometry.self_pair_checked`), the base against every fixture (the robot is
mounted on one), the tool against the wrist 2 and wrist 3 bodies, the part against the
tool and wrist 3, fixtures against each other.

Every checked pair must keep a signed distance above its required clearance: the model's
``clearance_m`` by default, or what a :class:`ContactAllowance` grants (e.g. the part may
touch the pallet it is placed on, down to -1 mm, while every other fixture keeps the full
clearance). A state is valid when every pair keeps its clearance plus ``STALL_M``.

Motion checking (:meth:`CollisionModel.check_motion`) is conservative advancement, exact
up to the tolerance ``STALL_M``. Along the joint-space segment q(s) = q0 + s (q1 - q0),
s in [0, 1], a point p of an object carried by joint k moves with speed

    |dp/ds| = |sum_{j<=k} (q1_j - q0_j) w_j x (p - o_j)| <= sum_{j<=k} |q1_j - q0_j| r_j(p)

where o_j and w_j are a point and the unit direction of joint j's axis and r_j(p) the
distance of p from that axis. We bound r_j(p) for every configuration by ``R[obj, j]``
(:func:`.motion_bounds.joint_reach`): along the chain p - o_j = t_(j+1) + ... + t_k + (p - o_k), the
components across axis j of the fixed link offsets t_m (their x-y part while the axes of
joints j..m-1 stay parallel to axis j, their whole length after that) plus the largest
distance of the object from joint k's origin, or from its axis when that is parallel too,
taken over the object's support points (:func:`.motion_bounds.support_points`: a convex part's vertices,
capsule ends + radius, box corners, ...), whose hull (plus the pad) contains the object. Hence over any sub-segment [s, s + ds] no point of the object moves
more than ``ds * sum_j R[obj, j] |q1_j - q0_j|``, and the distance of a pair shrinks by
at most ``ds * c_pair``, with ``c_pair`` that bound for the moving object against a static
one; for two objects carried by arm bodies a < b the distance is measured in body a's
frame, where only joints a+1..b move body b, so only those joints count.

:meth:`CollisionModel.check_motion` tightens ``c_pair`` per part of the segment (parts of
at most ``KNOT_STEP_RAD``): it measures each object's distance from each axis at the
part's ends, and since only the joints after j change r_j, at rate at most
``A_j = sum_(i>j) R[obj, i] |dq_i|``, r_j stays below ``(r_j(start) + r_j(end) + A_j) / 2``
over the part (:meth:`CollisionModel.segment_bounds`); the bound on the shrink is then
piecewise linear in s. If the distance at s exceeds the required clearance by ``m``, the
pair is provably fine until that bound has grown by ``m``. The checker jumps from one
such horizon to the next, re-measuring only the pairs whose horizon ran out (exact coal
distances), and reports a collision when a pair's margin falls below ``STALL_M`` (0.1 mm;
also what guarantees termination). Nothing can slip between checks, however thin the
obstacle.
"""

from __future__ import annotations

import bisect
import functools
import heapq
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.model.geometry import Placed, Shape
from cellrunner.planning.collision_scene import (
    STALL_M,
    TOOL_ADJACENT_BODIES,
    Clearance,
    CollisionScene,
    ContactAllowance,
    _hashable,
)
from cellrunner.planning.motion_bounds import bisection_order

__all__ = [
    "STALL_M",
    "TOOL_ADJACENT_BODIES",
    "Clearance",
    "CollisionModel",
    "ContactAllowance",
    "MotionCheck",
]

#: Spacing (largest joint move, rad) of the cheap rejection probes in check_motion.
PROBE_STEP_RAD = 0.15

#: check_path bounds the polyline chunk by chunk, each chunk about ``KNOT_STEP_RAD`` of joint
#: travel (as check_motion's parts): the chunk's radial bounds bound its segments, and the
#: lower bounds at the chunk ends prove the pairs that stay clear of it, so only the others
#: are measured.
#: off: every pair bounded by its configuration-independent reach and measured (the test of
#: the chunked bounds compares the two)
PATH_CHUNK_BOUNDS = True

#: Largest joint move (rad) of one part of a segment over which check_motion bounds each
#: object's distance from the joint axes afresh (shorter parts: tighter bounds, more FK).
KNOT_STEP_RAD = 0.2

#: derived models (carried part x contact allowances) kept per cell
VARIANTS_KEPT = 64


@dataclass(frozen=True)
class MotionCheck:
    """Result of :meth:`CollisionModel.check_motion`: ``ok``, the first blocked fraction
    of the segment (``s_blocked``, None when ok), the pair, and how many exact distance
    queries were needed."""

    ok: bool
    s_blocked: float | None = None
    clearance: Clearance | None = None
    distance_queries: int = 0


class CollisionModel(CollisionScene):
    """Static collision world of one cell plus the robot; cheap derived copies carry a part
    or grant contact allowances (:meth:`carrying`, :meth:`allowing`), and the motion checks
    (:meth:`check_motion`, :meth:`check_path`).

    Parameters: ``kinematics`` (the arm and its mount), ``tool`` shapes in the flange
    frame, ``fixtures`` shapes in the world, ``clearance_m`` the distance every checked
    pair must keep (m).
    """

    @functools.cached_property
    def _variants(self) -> dict[Any, CollisionModel]:
        """The models derived from this one, by their key (shared with each of them)."""
        key = self._key(self.part, self.allowances, self.clearance_m)
        return {key: self} if _hashable(key) else {}

    # -- derived models -------------------------------------------------------------------

    def carrying(self, part: Placed | None) -> CollisionModel:
        """The same cell with ``part`` (placed in the TCP frame) held, or none."""
        return self._variant(part, self.allowances, self.clearance_m)

    def allowing(self, *allowances: ContactAllowance) -> CollisionModel:
        """The same cell and part with these contact allowances (replacing earlier ones)."""
        return self._variant(self.part, tuple(allowances), self.clearance_m)

    def keeping(self, clearance_m: float) -> CollisionModel:
        """The same cell, part and allowances, every other pair keeping ``clearance_m``
        (a step's own ``clearance:``, SPEC section 12 tight fits)."""
        return self._variant(self.part, self.allowances, float(clearance_m))

    @staticmethod
    def _key(
        part: Placed | None, allowances: tuple[ContactAllowance, ...], clearance_m: float
    ) -> tuple[Any, ...]:
        return (_placed_key(part), allowances, clearance_m)

    def _variant(
        self, part: Placed | None, allowances: tuple[ContactAllowance, ...], clearance_m: float
    ) -> CollisionModel:
        """The model of this cell with ``part``, ``allowances`` and ``clearance_m``, built
        once per cell and such state and shared by every model derived from the same one
        (models keep no state between queries)."""
        key = self._key(part, allowances, clearance_m)
        if key == self._key(self.part, self.allowances, self.clearance_m):
            return self
        model = (
            self._variants.get(key) if _hashable(key) else None
        )  # a shape holding a list: not kept
        if model is None:
            model = CollisionModel(
                self.kinematics,
                self.tool,
                self.fixtures,
                clearance_m,
                part=part,
                allowances=allowances,
                _geometry_cache=self._geometry_cache,
            )
            model._variants = self._variants
            if _hashable(key):
                if len(self._variants) >= VARIANTS_KEPT:  # parts in ever new poses: stay bounded
                    self._variants.clear()
                self._variants[key] = model
        return model

    # -- motion bounds (:class:`.collision_bounds.PairBounds`) -----------------------------

    def motion_coefficients(self, dq_rad: np.ndarray) -> np.ndarray:
        """:meth:`PairBounds.motion_coefficients`: per pair, the bound on the distance
        shrink over any segment with joint displacement ``dq_rad`` (m)."""
        return self.bounds.motion_coefficients(dq_rad)

    def segment_bounds(self, q0_rad: np.ndarray, q1_rad: np.ndarray, pieces: int = 1) -> np.ndarray:
        """:meth:`PairBounds.segment_bounds`: (pieces, pairs) shrink bounds along q0 -> q1."""
        return self.bounds.segment_bounds(q0_rad, q1_rad, pieces)

    def joint_frames(self, q_rad: np.ndarray) -> np.ndarray:
        """:meth:`PairBounds.joint_frames`: world frames of joints 0..6 (n, 7, 4, 4)."""
        return self.bounds.joint_frames(q_rad)

    # -- motion checks --------------------------------------------------------------------

    def check_motion(
        self, q0_rad: np.ndarray, q1_rad: np.ndarray, *, explain: bool = True, probe: bool = True
    ) -> MotionCheck:
        """Whether the straight joint-space segment q0 -> q1 keeps every clearance, by
        conservative advancement (provably complete up to ``STALL_M``; module docstring).

        The motion bound of each pair is tightened per part of the segment (parts of at
        most ``KNOT_STEP_RAD`` of the largest joint move; :meth:`segment_bounds`), so the
        advancement takes long steps where the moving objects are close to the axes that
        turn. A coarse pass of state checks (every ``PROBE_STEP_RAD`` of the largest joint
        move, bisection order) first rejects most blocked motions cheaply; it proves nothing
        and is never used to accept one (``probe=False`` skips it, for edges already
        sampled finer). ``explain=False`` skips naming the blocking pair.
        """
        q0 = np.asarray(q0_rad, float)
        dq = np.asarray(q1_rad, float) - q0
        if not len(self._pairs):
            return MotionCheck(True)
        largest = float(np.abs(dq).max())
        if probe:
            for s in bisection_order(math.ceil(largest / PROBE_STEP_RAD)):
                if not self.is_valid(q0 + s * dq):
                    return MotionCheck(False, s, self.clearance(q0 + s * dq) if explain else None)
        pieces = max(1, math.ceil(largest / KNOT_STEP_RAD))
        rates, lower = self.bounds.knots(q0, q0 + dq, pieces)
        rates = np.maximum(rates, 1e-12)  # (pieces, pairs)
        # a part is proven for a pair by the lower bounds at its two ends alone when even
        # the worst shrink between them leaves the clearance: d >= (lb_a + lb_b - rate) / 2;
        # resume[k][p]: the first part >= p that pair k's lower bounds leave open (pieces:
        # none), so a pair proven into a closed part is next measured where that part ends
        open_parts = 0.5 * (lower[:-1] + lower[1:] - rates) - self._required < STALL_M
        index = np.where(open_parts, np.arange(pieces)[:, None], pieces)
        resume = np.minimum.accumulate(index[::-1], axis=0)[::-1].T.tolist()
        # cum[k][i]: bound on pair k's shrink over s in [0, i / pieces] (strictly rising)
        cum = np.concatenate([np.zeros((1, rates.shape[1])), np.cumsum(rates, axis=0)]).T.tolist()
        required = self._required_list
        model, data, gm, gd = self.kinematics.model, self._data, self._geom_model, self._geom_data
        import pinocchio as pin  # loaded with the scene; the local name keeps the loop fast

        update, distance = pin.updateGeometryPlacements, pin.computeDistance
        bisect_right, last_part = bisect.bisect_right, pieces - 1
        queries = 0
        due: list[tuple[float, int]] = []  # (s, pair): proven fine up to s, measure there next
        for k, rows in enumerate(resume):
            if rows[0] < pieces:
                due.append((rows[0] / pieces, k))
        heapq.heapify(due)
        pop, push = heapq.heappop, heapq.heappush
        s = -1.0
        while due:
            if due[0][0] > s:
                s = due[0][0]
                update(model, data, gm, gd, q0 + s * dq)
            k = pop(due)[1]
            m = distance(gm, gd, k).min_distance - required[k]
            queries += 1
            if m < STALL_M:
                return self._blocked(s, k, m, queries)
            # proven fine while the bound has grown by less than m (piecewise linear in s)
            c, x = cum[k], s * pieces
            i = min(int(x), last_part)
            target = c[i] + (x - i) * (c[i + 1] - c[i]) + m
            if target >= c[pieces]:
                continue
            j = bisect_right(c, target) - 1
            resume_at = resume[k][j]
            if resume_at == j:  # part j is open: measure where the proof ends
                push(due, ((j + (target - c[j]) / (c[j + 1] - c[j])) / pieces, k))
            elif resume_at < pieces:  # closed by the lower bounds up to that part
                push(due, (resume_at / pieces, k))
        return MotionCheck(True, distance_queries=queries)

    def _blocked(self, s: float, k: int, margin: float, queries: int) -> MotionCheck:
        a, b = self._pairs[k]
        required = float(self._required[k])
        return MotionCheck(
            False,
            s,
            Clearance(
                float(margin) + required,
                required + STALL_M,
                self._objects[a].label,
                self._objects[b].label,
            ),
            queries,
        )

    def check_path(self, q_rad: np.ndarray) -> MotionCheck:
        """:meth:`check_motion` over the polyline through ``q_rad`` (N x 6), proven the same
        way but sharing distance queries across segments: a pair measured at sample j with
        margin m is fine up to the last sample k whose accumulated motion bound
        ``sum_{i=j..k-1} c_pair(q_i -> q_i+1)`` stays below m - STALL_M; it is measured
        again there. Where no single measurement covers a segment, that pair alone is
        advanced along it by its own bound. The bounds come from chunks of the path
        (:meth:`_chunk_bounds`); pairs that the lower bounds at the chunks' ends prove on
        every chunk (as in :meth:`check_motion`) are never measured. ``s_blocked`` is the
        sample index (plus segment fraction)."""
        q = np.asarray(q_rad, float)
        if not len(self._pairs) or len(q) == 0:
            return MotionCheck(True)
        if len(q) == 1:
            ok = self.is_valid(q[0])
            return MotionCheck(ok, None if ok else 0.0, None if ok else self.clearance(q[0]))
        n = len(q)
        adq = np.abs(np.diff(q, axis=0))  # (n-1, 6)
        if PATH_CHUNK_BOUNDS:
            pairs, seg_t = self._chunk_bounds(q, adq)
            if not len(pairs):
                return MotionCheck(True)
        else:
            pairs = np.arange(len(self._pairs))
            seg_t = adq @ self.bounds.pair_reach.T  # (n-1, pairs)
        # summed along the samples in (n, pairs) layout, then one transposing copy: a cumsum
        # along the rows of (pairs, n) strides through memory (4x slower, measured)
        cum_t = np.empty((n, len(pairs)))
        cum_t[0] = 0.0
        np.cumsum(seg_t, axis=0, out=cum_t[1:])
        # rows of the pairs measured, by pair index
        seg_rows, cum_rows = seg_t.T, np.ascontiguousarray(cum_t.T)  # (open, n-1), (open, n)
        seg = dict(zip(pairs.tolist(), seg_rows, strict=True))
        cum = dict(zip(pairs.tolist(), cum_rows, strict=True))
        # due[j]: the pairs to measure at sample j; ``samples``: the keys, sorted. A pair
        # proven up to sample ``last`` joins the latest sample already due in
        # (j + (last - j) / 2, last] if there is one (measuring it earlier is as sound and
        # shares that sample's placement update), else it is due at ``last``
        due: dict[int, list[int]] = {0: pairs.tolist()}
        samples = [0]
        model, data, gm, gd = self.kinematics.model, self._data, self._geom_model, self._geom_data
        import pinocchio as pin  # loaded with the scene; the local name keeps the loop fast

        update, distance = pin.updateGeometryPlacements, pin.computeDistance
        required = self._required_list
        insort, bisect_right = bisect.insort, bisect.bisect_right
        queries = 0
        while samples:
            j = samples.pop(0)
            qj = q[j]
            update(model, data, gm, gd, qj)
            for k in due.pop(j):
                m = distance(gm, gd, k).min_distance - required[k]
                queries += 1
                if m < STALL_M:
                    return self._blocked(float(j), k, m, queries)
                row = cum[k]
                last = int(row.searchsorted(row[j] + m - STALL_M, side="right")) - 1
                if last <= j:
                    # this pair alone, advanced along the segment by its own bound
                    s_blocked, m_blocked, used = self._advance_pair(
                        k, qj, q[j + 1], float(seg[k][j]), m
                    )
                    queries += used
                    if s_blocked is not None:
                        return self._blocked(j + s_blocked, k, m_blocked, queries)
                    update(model, data, gm, gd, qj)  # the other pairs due here: at sample j
                    last = j + 1
                if last >= n - 1:
                    continue
                i = bisect_right(samples, last)
                if i and 2 * samples[i - 1] > j + last:
                    due[samples[i - 1]].append(k)
                elif last in due:
                    due[last].append(k)
                else:
                    due[last] = [k]
                    insort(samples, last)
        return MotionCheck(True, distance_queries=queries)

    def _chunk_bounds(self, q: np.ndarray, adq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For the polyline ``q`` (n x 6, |dq| per segment ``adq``) cut into chunks
        of about ``KNOT_STEP_RAD`` of joint travel: the pairs that some chunk's end lower bounds do not prove
        clear (as in :meth:`check_motion`), and for those, per segment, a bound on the
        distance shrink along it (n - 1, open pairs), from its chunk's bounds."""
        n = len(q)
        chunks = max(1, math.ceil(float(adq.sum(axis=0).max()) / KNOT_STEP_RAD))
        size = math.ceil((n - 1) / chunks)
        cuts = np.arange(0, n - 1, size)
        travel = np.add.reduceat(adq, cuts, axis=0)  # (chunks, 6)
        per_pair, lower = self.bounds.piece_bounds(q[np.append(cuts, n - 1)], travel)
        rates = np.einsum("cpj,cj->cp", per_pair, travel)
        open_chunks = 0.5 * (lower[:-1] + lower[1:] - rates) - self._required < STALL_M
        pairs = np.flatnonzero(open_chunks.any(axis=0))
        if not len(pairs):
            return pairs, np.empty((n - 1, 0))
        padded = np.zeros((len(cuts) * size, 6))
        padded[: n - 1] = adq
        steps = padded.reshape(len(cuts), size, 6) @ per_pair[:, pairs].transpose(0, 2, 1)
        return pairs, np.maximum(steps.reshape(-1, len(pairs))[: n - 1], 1e-12)

    def _advance_pair(
        self, k: int, qa: np.ndarray, qb: np.ndarray, shrink_m: float, margin_m: float
    ) -> tuple[float | None, float, int]:
        """Conservative advancement of pair ``k`` alone along qa -> qb, where its distance
        shrinks by at most ``shrink_m`` and it has ``margin_m`` at qa: (the blocked
        fraction or None, the margin there, exact queries made)."""
        s, m, used = 0.0, margin_m, 0
        required = self._required_list[k]
        rate = max(shrink_m, 1e-12)
        import pinocchio as pin

        while True:
            s += m / rate
            if s >= 1.0:
                return None, m, used
            self._update(qa + s * (qb - qa))
            m = pin.computeDistance(self._geom_model, self._geom_data, k).min_distance - required
            used += 1
            if m < STALL_M:
                return s, m, used


def _placed_key(placed: Placed | None) -> tuple[str, Shape, bytes] | None:
    """What a placed shape is, by value (a part placed again in the same pose is the same)."""
    if placed is None:
        return None
    return placed.name, placed.shape, np.asarray(placed.T_parent_shape, float).tobytes()
