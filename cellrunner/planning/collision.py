"""Collision model of the arm, its tool, a carried part and the cell's fixtures (coal).

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
import heapq
import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.arm_geometry import ArmGeometry, ArmGeometryMissing, ConvexPart, arm_geometry
from cellrunner.model.geometry import Placed, Shape
from cellrunner.planning.coal_shapes import make_coal_shape, world_aabb
from cellrunner.planning.motion_bounds import (
    bisection_order,
    cover_spheres,
    joint_reach,
    polytope_cover_spheres,
    support_points,
)

if TYPE_CHECKING:
    import coal
    import pinocchio as pin

    from cellrunner.planning.kinematics import ArmKinematics
else:

    class _LazyModule:
        """Imports ``name`` on first attribute access and takes its place in this module's
        globals: ``ContactAllowance`` and the cache need no pinocchio or coal (~0.1-0.4 s)."""

        def __init__(self, name: str, alias: str) -> None:
            self._name, self._alias = name, alias

        def __getattr__(self, attr: str):
            module = importlib.import_module(self._name)
            globals()[self._alias] = module
            return getattr(module, attr)

    coal = _LazyModule("coal", "coal")
    pin = _LazyModule("pinocchio", "pin")

#: Margin below which a pair counts as colliding in addition to its required clearance;
#: keeps conservative advancement finite (m).
STALL_M = 1e-4

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

#: Arm bodies the tool is rigidly attached to or adjacent to (never checked against it).
TOOL_ADJACENT_BODIES = frozenset({5, 6})


@dataclass(frozen=True)
class ContactAllowance:
    """Let the ``robot_part`` ("tool" or "part") come within ``min_clearance_m`` of fixture
    ``fixture`` (negative: it may touch and press in by that much) instead of the full
    clearance. Used for grasp and placement contacts, e.g. the jaws reaching around a part
    on the table, or the carried part set down on the pallet."""

    fixture: str
    robot_part: str = "part"
    min_clearance_m: float = -0.001

    def __post_init__(self) -> None:
        if self.robot_part not in ("tool", "part"):
            raise ValueError(f"robot_part must be 'tool' or 'part', not {self.robot_part!r}")


@dataclass(frozen=True)
class Clearance:
    """The closest pair at a configuration: its signed distance and what it must keep."""

    distance_m: float
    required_m: float
    a: str
    b: str

    @property
    def margin_m(self) -> float:
        return self.distance_m - self.required_m

    def describe(self) -> str:
        """'tool collides with fixture 'table' (3.0 mm deep; keeps >= 2.0 mm)' or
        'upper_arm is too close to fixture 'wall' (1.96 mm apart, 0.14 mm short of 2.1 mm)':
        the shortfall is printed with enough digits never to read as no shortfall."""
        if self.distance_m <= 0:
            return (
                f"{self.a} collides with {self.b} ({-self.distance_m * 1000:.1f} mm deep; "
                f"must keep {self.required_m * 1000:.1f} mm)"
            )
        short_mm = (self.required_m - self.distance_m) * 1000
        digits = 1 if short_mm >= 0.1 else 2 if short_mm >= 0.01 else 3
        return (
            f"{self.a} is too close to {self.b} ({self.distance_m * 1000:.{digits}f} mm apart, "
            f"{short_mm:.{digits}f} mm short of the {self.required_m * 1000:.1f} mm it must keep)"
        )


@dataclass(frozen=True)
class MotionCheck:
    """Result of :meth:`CollisionModel.check_motion`: ``ok``, the first blocked fraction
    of the segment (``s_blocked``, None when ok), the pair, and how many exact distance
    queries were needed."""

    ok: bool
    s_blocked: float | None = None
    clearance: Clearance | None = None
    distance_queries: int = 0


@dataclass(frozen=True)
class _Object:
    label: str  # for messages: "upper_arm", "tool 'gripper'", "fixture 'table'"
    group: str  # "arm" | "tool" | "part" | "fixture"
    body: int  # 0..6 for robot objects (0 = base / world), -1 for fixtures
    geometry: coal.CollisionGeometry = field(compare=False)
    placement: np.ndarray = field(compare=False)  # T_joint_shape (fixtures: T_world_shape)
    radius_m: float = 0.0  # bounding sphere radius about the shape origin
    fixture: str = ""
    part: ConvexPart | None = field(default=None, compare=False)  # arm parts: the polytope


class CollisionModel:
    """Static collision world of one cell plus the robot; cheap derived copies carry a part
    or grant contact allowances (:meth:`carrying`, :meth:`allowing`).

    Parameters: ``kinematics`` (the arm and its mount), ``tool`` shapes in the flange
    frame, ``fixtures`` shapes in the world, ``clearance_m`` the distance every checked
    pair must keep (m).
    """

    def __init__(
        self,
        kinematics: ArmKinematics,
        tool: Sequence[Placed] = (),
        fixtures: Sequence[Placed] = (),
        clearance_m: float = 0.002,
        *,
        part: Placed | None = None,
        allowances: Sequence[ContactAllowance] = (),
        _geometry_cache: dict[Any, Any] | None = None,
    ) -> None:
        self.kinematics = kinematics
        self.tool = tuple(tool)
        self.fixtures = tuple(fixtures)
        self.clearance_m = float(clearance_m)
        self.part = part
        self.allowances = tuple(allowances)
        names = [f.name for f in self.fixtures]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"duplicate fixture names: {', '.join(duplicates)}")
        for allowance in self.allowances:
            if allowance.fixture not in names:
                raise ValueError(
                    f"contact allowance names unknown fixture {allowance.fixture!r}; "
                    f"known: {', '.join(names) or '(none)'}"
                )
        self._geometry_cache = _geometry_cache if _geometry_cache is not None else {}
        self._build()
        key = (_placed_key(part), self.allowances)
        self._variants: dict[Any, CollisionModel] = {key: self} if _hashable(key) else {}

    # -- derived models -------------------------------------------------------------------

    def carrying(self, part: Placed | None) -> CollisionModel:
        """The same cell with ``part`` (placed in the TCP frame) held, or none."""
        return self._variant(part, self.allowances)

    def allowing(self, *allowances: ContactAllowance) -> CollisionModel:
        """The same cell and part with these contact allowances (replacing earlier ones)."""
        return self._variant(self.part, tuple(allowances))

    def _variant(
        self, part: Placed | None, allowances: tuple[ContactAllowance, ...]
    ) -> CollisionModel:
        """The model of this cell with ``part`` and ``allowances``, built once per cell and
        such state and shared by every model derived from the same one (models keep no
        state between queries)."""
        key = (_placed_key(part), allowances)
        if key == (_placed_key(self.part), self.allowances):
            return self
        model = (
            self._variants.get(key) if _hashable(key) else None
        )  # a shape holding a list: not kept
        if model is None:
            model = CollisionModel(
                self.kinematics,
                self.tool,
                self.fixtures,
                self.clearance_m,
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

    # -- construction ---------------------------------------------------------------------

    def _coal_shape(self, shape: Shape) -> tuple[coal.CollisionGeometry, float]:
        key = shape if _hashable(shape) else id(shape)  # the same box read twice is one geometry
        cached = self._geometry_cache.get(key)
        if cached is not None and (cached[0] is shape or cached[0] == shape):
            return cached[1], cached[2]
        geometry, radius = make_coal_shape(shape)
        self._geometry_cache[key] = (shape, geometry, radius)
        return geometry, radius

    @staticmethod
    def _arm_geometry(model: str) -> ArmGeometry:
        try:
            return arm_geometry(model)
        except ArmGeometryMissing as exc:
            raise InfeasibleError(str(exc)) from None

    def _convex(self, part: ConvexPart) -> coal.CollisionGeometry:
        """The coal polytope of an arm part (built once per cell and shared by variants)."""
        key = ("arm part", id(part))
        cached = self._geometry_cache.get(key)
        if cached is None or cached[0] is not part:
            vertices = coal.StdVec_Vec3s()
            vertices.extend(list(part.vertices_m))
            cached = (part, coal.Convex.convexHull(vertices, False, ""), 0.0)
            self._geometry_cache[key] = cached
        return cached[1]

    def _build(self) -> None:
        kin = self.kinematics
        model = kin.model
        spec = kin.spec
        objects: list[_Object] = []
        self._arm = self._arm_geometry(spec.arm)
        for part in self._arm.parts:
            objects.append(
                _Object(
                    part.link,
                    "arm",
                    part.body,
                    self._convex(part),
                    np.eye(4),
                    radius_m=float(np.linalg.norm(part.vertices_m, axis=1).max()),
                    part=part,
                )
            )
        T_joint6_flange = model.frames[kin.flange_frame_id].placement.homogeneous
        for placed in self.tool:
            geometry, radius = self._coal_shape(placed.shape)
            objects.append(
                _Object(
                    f"tool {placed.name!r}",
                    "tool",
                    6,
                    geometry,
                    T_joint6_flange @ placed.T_parent_shape,
                    radius_m=radius,
                )
            )
        if self.part is not None:
            geometry, radius = self._coal_shape(self.part.shape)
            T_joint6_tcp = T_joint6_flange @ kin.T_flange_tcp
            objects.append(
                _Object(
                    f"part {self.part.name!r}",
                    "part",
                    6,
                    geometry,
                    T_joint6_tcp @ self.part.T_parent_shape,
                    radius_m=radius,
                )
            )
        for placed in self.fixtures:
            geometry, radius = self._coal_shape(placed.shape)
            objects.append(
                _Object(
                    f"fixture {placed.name!r}",
                    "fixture",
                    -1,
                    geometry,
                    np.asarray(placed.T_parent_shape, float),
                    radius_m=radius,
                    fixture=placed.name,
                )
            )
        self._objects = objects

        geom_model = pin.GeometryModel()
        for k, obj in enumerate(objects):
            if obj.group == "fixture":
                joint, placement = 0, obj.placement
            elif obj.body == 0:
                joint, placement = 0, kin.T_world_base @ obj.placement
            else:
                joint, placement = obj.body, obj.placement
            geom_model.addGeometryObject(
                pin.GeometryObject(f"g{k}", joint, pin.SE3(placement), obj.geometry)
            )

        pairs: list[tuple[int, int]] = []
        required: list[float] = []
        for i, a in enumerate(objects):
            for j in range(i + 1, len(objects)):
                b = objects[j]
                if not self._checked(a, b):
                    continue
                pairs.append((i, j))
                required.append(self._required_m(a, b))
        for i, j in pairs:
            geom_model.addCollisionPair(pin.CollisionPair(i, j))
        self._geom_model = geom_model
        self._geom_data = pin.GeometryData(geom_model)
        self._data = model.createData()
        self._pairs = np.array(pairs, dtype=int).reshape(-1, 2)
        self._required = np.array(required, dtype=float)
        self._required_list = self._required.tolist()
        for k, req in enumerate(self._geom_data.collisionRequests):
            req.security_margin = float(self._required[k] + STALL_M)
            req.num_max_contacts = 1
        # AABB culling before the exact tests; pinocchio inflates each object's box by the
        # largest security margin of its pairs, so no pair within its clearance is culled
        self._broadphase = pin.BroadPhaseManager_NaiveCollisionManager(
            model, geom_model, self._geom_data
        )
        self._prepare_bounds()

    def _checked(self, a: _Object, b: _Object) -> bool:
        groups = {a.group, b.group}
        if groups == {"fixture"}:
            return False
        if "fixture" in groups:
            robot = a if b.group == "fixture" else b
            return robot.body != 0
        if a.group == b.group == "arm":
            assert a.part is not None and b.part is not None
            return self._arm.self_pair_checked(
                self._arm.parts.index(a.part), self._arm.parts.index(b.part), self.clearance_m
            )
        if groups == {"tool"} or groups == {"part"}:
            return False
        if groups == {"tool", "part"}:
            return False
        other = a if a.group == "arm" else b
        mover = b if other is a else a
        if mover.group == "tool":
            return other.body not in TOOL_ADJACENT_BODIES
        return other.body != 6  # part against the arm

    def _required_m(self, a: _Object, b: _Object) -> float:
        fixture = a if a.group == "fixture" else b if b.group == "fixture" else None
        if fixture is not None:
            mover = b if fixture is a else a
            for allowance in self.allowances:
                if allowance.fixture == fixture.fixture and allowance.robot_part == mover.group:
                    return allowance.min_clearance_m
        return self.clearance_m

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
        self._covers = {int(k): self._cover_spheres(self._objects[k]) for k in movers}
        radial = [
            self._covers[int(k)]
            if self._objects[k].part is not None
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
        self._pair_reach = self._reach[self._pair_high] * self._pair_joints
        # row of each pair's counting object in the movers' support arrays
        self._pair_high_row = np.searchsorted(movers, self._pair_high)
        self._prepare_lower_bounds()

    @staticmethod
    def _cover_spheres(obj: _Object) -> tuple[np.ndarray, np.ndarray]:
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

    # -- queries --------------------------------------------------------------------------

    @property
    def pinocchio_geometry(self) -> pin.GeometryModel:
        """The coal geometry with its checked pairs, on :attr:`ArmKinematics.model` (for
        tools that take pinocchio models, e.g. the benchmark's baseline planner)."""
        return self._geom_model

    @property
    def pair_labels(self) -> list[tuple[str, str]]:
        return [(self._objects[i].label, self._objects[j].label) for i, j in self._pairs]

    def _update(self, q_rad: np.ndarray) -> None:
        pin.updateGeometryPlacements(
            self.kinematics.model,
            self._data,
            self._geom_model,
            self._geom_data,
            np.asarray(q_rad, float),
        )

    def is_valid(self, q_rad: np.ndarray) -> bool:
        """True when every checked pair keeps its required clearance (+ ``STALL_M``)."""
        if not len(self._pairs):
            return True
        pin.updateGeometryPlacements(
            self.kinematics.model,
            self._data,
            self._geom_model,
            self._geom_data,
            np.asarray(q_rad, float),
        )
        self._broadphase.update(False)
        return not pin.computeCollisions(self._broadphase, True)

    def clearance(self, q_rad: np.ndarray) -> Clearance:
        """The pair with the smallest margin over its required clearance at ``q_rad``."""
        if not len(self._pairs):
            return Clearance(math.inf, self.clearance_m, "robot", "nothing")
        self._update(q_rad)
        distances = self._exact(np.arange(len(self._pairs)))
        k = int(np.argmin(distances - self._required))
        a, b = self._pairs[k]
        return Clearance(
            float(distances[k]),
            float(self._required[k]),
            self._objects[a].label,
            self._objects[b].label,
        )

    def pair_distances(self, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (m) and required clearance (m) of every checked pair at
        ``q_rad``, in :meth:`pair_labels` order (the jog governor watches fixtures)."""
        if not len(self._pairs):
            return np.empty(0), np.empty(0)
        self._update(q_rad)
        return self._exact(np.arange(len(self._pairs))), np.asarray(self._required, float)

    def violations(self, q_rad: np.ndarray) -> list[Clearance]:
        """Every checked pair closer than its required clearance (+ ``STALL_M``) at
        ``q_rad``, closest first (what blocks a state, for diagnostics)."""
        distances, required = self.pair_distances(q_rad)
        out = []
        for k in np.flatnonzero(distances - required < STALL_M):
            a, b = self._pairs[k]
            out.append(
                Clearance(
                    float(distances[k]),
                    float(required[k]),
                    self._objects[a].label,
                    self._objects[b].label,
                )
            )
        return sorted(out, key=lambda c: c.margin_m)

    def min_distance(self, q_rad: np.ndarray) -> tuple[float, str, str]:
        """The smallest signed distance over the checked pairs (m) and their names."""
        if not len(self._pairs):
            return math.inf, "robot", "nothing"
        self._update(q_rad)
        distances = self._exact(np.arange(len(self._pairs)))
        k = int(np.argmin(distances))
        a, b = self._pairs[k]
        return float(distances[k]), self._objects[a].label, self._objects[b].label

    def _exact(self, indices: np.ndarray) -> np.ndarray:
        out = np.empty(len(indices))
        for n, k in enumerate(indices):
            out[n] = pin.computeDistance(self._geom_model, self._geom_data, int(k)).min_distance
        return out

    def motion_coefficients(self, dq_rad: np.ndarray) -> np.ndarray:
        """Per pair, the bound on how much its distance can shrink over the whole segment
        with joint displacement ``dq_rad`` (m), valid for any segment; see the module
        docstring."""
        return np.asarray(self._pair_reach @ np.abs(np.asarray(dq_rad, float)))

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
        return self._knots(q0_rad, q1_rad, pieces)[0]

    def _knots(
        self, q0_rad: np.ndarray, q1_rad: np.ndarray, pieces: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`segment_bounds` (pieces, pairs) and, at the ``pieces + 1`` part ends,
        lower bounds of every pair's signed distance (pieces + 1, pairs), in m."""
        q0 = np.asarray(q0_rad, float)
        dq = (np.asarray(q1_rad, float) - q0) / pieces
        return self._polyline_bounds(q0 + np.arange(pieces + 1)[:, None] * dq)

    def _polyline_bounds(self, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For the polyline through ``q_rad`` (knots x 6): per segment and pair, the bound
        on the distance shrink along the segment (:meth:`segment_bounds`), and per knot
        and pair, a lower bound of the signed distance (:meth:`_knot_lower_bounds`)."""
        q = np.asarray(q_rad, float)
        adq = np.abs(np.diff(q, axis=0))  # (pieces, 6)
        per_pair, lower = self._piece_bounds(q, adq)
        return np.einsum("kpj,kj->kp", per_pair, adq), lower

    def _piece_bounds(self, q: np.ndarray, travel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
        rates, lower = self._knots(q0, q0 + dq, pieces)
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
            seg_t = adq @ self._pair_reach.T  # (n-1, pairs)
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
        per_pair, lower = self._piece_bounds(q[np.append(cuts, n - 1)], travel)
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


def _hashable(value: object) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True
