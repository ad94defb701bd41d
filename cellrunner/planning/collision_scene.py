"""The static collision scene of one cell: the arm's convex parts, its tool, a carried part
and the fixtures as coal shapes on a pinocchio geometry model, the pairs that are
checked, what clearance each must keep, and queries at one configuration.

Objects and frames:

- arm: the convex parts of :func:`cellrunner.model.arm_geometry.arm_geometry` (derived from
  Universal Robots' collision meshes, which they contain), on pinocchio joint i (body 0 =
  base, fixed at the mount). Names: the links', ``base``, ``shoulder``, ``upper_arm``,
  ``forearm``, ``wrist_1``, ``wrist_2``, ``wrist_3``. A model without derived geometry is
  refused (:class:`InfeasibleError`), never guessed.
- tool: shapes placed in the flange frame (``Placed.T_parent_shape`` = ``T_flange_shape``).
- part: the carried part, placed in the TCP frame (``T_tcp_shape``).
- fixtures: shapes placed in the world (``T_world_shape``): box, cylinder, sphere, STL mesh.
  A fixture named ``part:NAME`` is part NAME waiting at its frame (label ``waiting part
  'NAME'``): an obstacle like any fixture, except while that part is the one carried
  (it has left its frame: the carried part takes its place).

Pairs never checked (they touch by construction or are rigidly joined): arm parts that the
derivation proved apart by more than the clearance over the joints' ranges, or that are the
joint between adjacent links (:meth:`ArmGeometry.self_pair_checked`), the base against every
fixture (the robot is mounted on one), the tool against the wrist 2 and wrist 3 bodies, the
part against the tool and wrist 3, fixtures against each other.

Every checked pair must keep a signed distance above its required clearance: the scene's
``clearance_m`` by default, or what a :class:`ContactAllowance` grants (e.g. the part may
touch the pallet it is placed on, down to -1 mm, while every other fixture keeps the full
clearance). A state is valid when every pair keeps its clearance plus ``STALL_M``.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import InfeasibleError, InternalError
from cellrunner.model.arm_geometry import ArmGeometry, ArmGeometryMissing, ConvexPart, arm_geometry
from cellrunner.model.body import WAITING_PREFIX, Body, BodyKind, is_earlier_slot
from cellrunner.model.failure import Failure, FailureKind
from cellrunner.model.geometry import Placed, Shape
from cellrunner.model.gripper import JAW_PADS
from cellrunner.planning.coal_shapes import make_coal_shape
from cellrunner.planning.collision_bounds import PairBounds

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


def fixture_label(name: str) -> Body:
    """How messages name fixture ``name``: "fixture 'table'", or "waiting part 'block'"
    for a part waiting at its frame (:meth:`Body.fixture`)."""
    return Body.fixture(name)


#: what a scene without checked pairs names as its closest pair
_NO_PAIR = (Body(BodyKind.NOTHING, "robot"), Body(BodyKind.NOTHING, "nothing"))


#: Margin below which a pair counts as colliding in addition to its required clearance;
#: keeps conservative advancement finite (m).
STALL_M = 1e-4


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
            raise InternalError(f"robot_part must be 'tool' or 'part', not {self.robot_part!r}")


@dataclass(frozen=True)
class Clearance:
    """The closest pair at a configuration: its signed distance and what it must keep."""

    distance_m: float
    required_m: float
    a: Body
    b: Body

    @property
    def margin_m(self) -> float:
        return self.distance_m - self.required_m

    def describe(self) -> str:
        """'tool collides with fixture 'table' (3.0 mm deep; must keep 2.0 mm)', 'part 'p'
        presses 1.30 mm into fixture 'pallet', 0.30 mm more than the 1.00 mm it may' (a
        contact allowance, which must never read as a clearance below zero) or
        'upper_arm is too close to fixture 'wall' (1.96 mm apart, 0.14 mm short of 2.1 mm)':
        the shortfall is printed with enough digits never to read as no shortfall."""
        if self.distance_m <= 0 and self.required_m < 0:  # an allowance: it may press in
            over_mm = (self.required_m - self.distance_m) * 1000
            digits = 1 if over_mm >= 0.1 else 2 if over_mm >= 0.01 else 3
            return (
                f"{self.a} presses {-self.distance_m * 1000:.{digits}f} mm into {self.b}, "
                f"{over_mm:.{digits}f} mm more than the {-self.required_m * 1000:.{digits}f} mm "
                "it may"
            )
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
class SceneObject:
    """One collision object of the scene (arm part, tool shape, part or fixture)."""

    label: Body  # its text names it in messages: "upper_arm", "tool 'gripper'", "fixture 'table'"
    group: str  # "arm" | "tool" | "part" | "fixture"
    body: int  # 0..6 for robot objects (0 = base / world), -1 for fixtures
    geometry: coal.CollisionGeometry = field(compare=False)
    placement: np.ndarray = field(compare=False)  # T_joint_shape (fixtures: T_world_shape)
    radius_m: float = 0.0  # bounding sphere radius about the shape origin
    fixture: str = ""
    part: ConvexPart | None = field(default=None, compare=False)  # arm parts: the polytope


class CollisionScene:
    """Static collision world of one cell plus the robot, with a carried part and contact
    allowances, and the queries at one configuration.

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
            raise InternalError(f"duplicate fixture names: {', '.join(duplicates)}")
        for allowance in self.allowances:
            if allowance.fixture not in names:
                raise InternalError(
                    f"contact allowance names unknown fixture {allowance.fixture!r}; "
                    f"known: {', '.join(names) or '(none)'}"
                )
        self._geometry_cache = _geometry_cache if _geometry_cache is not None else {}
        self._build()

    # -- construction ---------------------------------------------------------------------

    def geometry_of(self, shape: Shape) -> coal.CollisionGeometry:
        """The coal geometry of ``shape``, built once per cell (a mesh is read once)."""
        return self._coal_shape(shape)[0]

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
            raise InfeasibleError(Failure(FailureKind.MODEL, str(exc))) from None

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
        self._arm = self._arm_geometry(kin.spec.arm)
        # each arm part's row (by identity: comparing parts compares their arrays)
        self._arm_row = {id(p): k for k, p in enumerate(self._arm.parts)}
        objects = self._scene_objects()
        self._objects = objects

        geom_model = _geometry_model(kin, objects)
        pairs, required = self._checked_pairs(objects)
        for i, j in pairs:
            geom_model.addCollisionPair(pin.CollisionPair(i, j))
        self._geom_model = geom_model
        self._geom_data = pin.GeometryData(geom_model)
        self._data = model.createData()
        self._pairs = np.array(pairs, dtype=int).reshape(-1, 2)
        self._required = np.array(required, dtype=float)
        self._required_list = self._required.tolist()
        surfaces = [isinstance(o.geometry, coal.BVHModelBase) for o in objects]
        for k, req in enumerate(self._geom_data.collisionRequests):
            margin = float(self._required[k] + STALL_M)
            i, j = pairs[k]
            if margin < 0.0 and (surfaces[i] or surfaces[j]):
                # coal measures no depth into a triangle surface (a mesh that does not fill
                # its hull) and refuses a negative margin for one: such a pair may touch,
                # never overlap (the twin's prisms of such a mesh are 2 mm thin)
                margin = 0.0
            req.security_margin = margin
            req.num_max_contacts = 1
        # AABB culling before the exact tests; pinocchio inflates each object's box by the
        # largest security margin of its pairs, so no pair within its clearance is culled
        self._broadphase = pin.BroadPhaseManager_NaiveCollisionManager(
            model, geom_model, self._geom_data
        )
        self.bounds = PairBounds(kin, objects, self._pairs)

    def _scene_objects(self) -> list[SceneObject]:
        """The arm's parts, the tool, the carried part and the fixtures, each on the body
        that carries it."""
        kin = self.kinematics
        model = kin.model
        objects: list[SceneObject] = []
        for part in self._arm.parts:
            objects.append(
                SceneObject(
                    Body(BodyKind.ROBOT_LINK, part.link),
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
                SceneObject(
                    Body(BodyKind.TOOL, placed.name),
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
                SceneObject(
                    Body(BodyKind.PART, self.part.name),
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
                SceneObject(
                    fixture_label(placed.name),
                    "fixture",
                    -1,
                    geometry,
                    np.asarray(placed.T_parent_shape, float),
                    radius_m=radius,
                    fixture=placed.name,
                )
            )
        return objects

    def _checked_pairs(
        self, objects: list[SceneObject]
    ) -> tuple[list[tuple[int, int]], list[float]]:
        """The pairs of ``objects`` checked against each other, with their clearances (m)."""
        pairs: list[tuple[int, int]] = []
        required: list[float] = []
        for i, a in enumerate(objects):
            for j in range(i + 1, len(objects)):
                b = objects[j]
                if not self._checked(a, b):
                    continue
                pairs.append((i, j))
                required.append(self._required_m(a, b))
        return pairs, required

    def _checked(self, a: SceneObject, b: SceneObject) -> bool:
        groups = {a.group, b.group}
        if groups == {"fixture"}:
            return False
        if "fixture" in groups:
            robot, fixture = (a, b) if b.group == "fixture" else (b, a)
            if self.part is not None and fixture.fixture == WAITING_PREFIX + self.part.name:
                return False  # the part carried is no longer waiting at its frame
            if robot.label.name in JAW_PADS and is_earlier_slot(fixture.fixture):
                return False  # open pads (check's model) beside a slot's part: placed.py
            return robot.body != 0
        if a.group == b.group == "arm":
            assert a.part is not None and b.part is not None
            return self._arm.self_pair_checked(
                self._arm_row[id(a.part)], self._arm_row[id(b.part)], self.clearance_m
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

    def _required_m(self, a: SceneObject, b: SceneObject) -> float:
        fixture = a if a.group == "fixture" else b if b.group == "fixture" else None
        if fixture is not None:
            mover = b if fixture is a else a
            for allowance in self.allowances:
                if allowance.fixture == fixture.fixture and allowance.robot_part == mover.group:
                    return allowance.min_clearance_m
        return self.clearance_m

    # -- queries --------------------------------------------------------------------------

    @property
    def pinocchio_geometry(self) -> pin.GeometryModel:
        """The coal geometry with its checked pairs, on :attr:`ArmKinematics.model` (for
        tools that take pinocchio models, e.g. the benchmark's baseline planner)."""
        return self._geom_model

    @property
    def pair_labels(self) -> list[tuple[Body, Body]]:
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
            return Clearance(math.inf, self.clearance_m, *_NO_PAIR)
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

    def min_distance(self, q_rad: np.ndarray) -> tuple[float, Body, Body]:
        """The smallest signed distance over the checked pairs (m) and their names."""
        if not len(self._pairs):
            return (math.inf, *_NO_PAIR)
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


def _geometry_model(kin: ArmKinematics, objects: list[SceneObject]) -> pin.GeometryModel:
    """The pinocchio geometry model of ``objects`` (the fixed ones in the world)."""
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
    return geom_model


def _hashable(value: object) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True
