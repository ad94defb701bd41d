"""Collision model: thin and touching obstacles, allowances, conservative motion checks."""

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.errors import InternalError
from cellrunner.model.arm_geometry import available_models
from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.collision import CollisionModel, ContactAllowance
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.stl import read_stl

HOME = np.radians([0, -90, 90, -90, -90, 0])
TOOL = (Placed("gripper", Cylinder(0.04, 0.15), pose_matrix((0, 0, 0.075))),)


def kin(model: str = "ur5e"):
    return ArmKinematics(ROBOTS[model], np.eye(4), pose_matrix((0, 0, 0.15)))


def test_home_is_free_and_reports_the_closest_pair():
    world = CollisionModel(
        kin(), TOOL, [Placed("table", Box((1.2, 1.2, 0.04)), pose_matrix((0, 0, -0.02)))]
    )
    assert world.is_valid(HOME)
    d, a, b = world.min_distance(HOME)
    assert d > 0.0 and a and b


def test_tool_in_a_box_is_named():
    k = kin()
    p = k.T_world_tcp(HOME)[:3, 3]
    world = CollisionModel(k, TOOL, [Placed("table", Box((0.3, 0.3, 0.05)), pose_matrix(p))])
    assert not world.is_valid(HOME)
    assert "tool 'gripper' collides with fixture 'table'" in world.clearance(HOME).describe()


def test_touching_obstacle_needs_an_allowance():
    k = kin()
    p = k.T_world_tcp(HOME)[:3, 3]
    # the tool points down at HOME: the part hangs 40 mm below the TCP onto the pallet's top
    plate = Placed("pallet", Box((0.3, 0.3, 0.02)), pose_matrix(p - [0, 0, 0.05]))
    part = Placed("block", Box((0.04, 0.04, 0.04)), pose_matrix((0, 0, 0.02)))
    world = CollisionModel(k, TOOL, [plate]).carrying(part)
    assert not world.is_valid(HOME)
    allowed = world.allowing(ContactAllowance("pallet", "part", -0.001))
    assert allowed.is_valid(HOME)
    assert (
        not allowed.carrying(Placed("deep", Box((0.04, 0.04, 0.04)), pose_matrix((0, 0, 0.03))))
        .allowing(ContactAllowance("pallet", "part", -0.001))
        .is_valid(HOME)
    )  # 10 mm into the pallet


def test_unknown_fixture_in_allowance_lists_known():
    with pytest.raises(InternalError, match="unknown fixture 'palet'; known: pallet"):
        CollisionModel(
            kin(),
            TOOL,
            [Placed("pallet", Box((1, 1, 1)), pose_matrix((3, 0, 0)))],
            allowances=[ContactAllowance("palet")],
        )


def _thin_plate_world(thickness):
    """A 2 mm plate that the tool tip crosses when joint 1 turns across -0.26 rad."""
    k = kin()
    p = k.T_world_tcp(HOME)[:3, 3]
    plate = Placed("plate", Box((0.4, thickness, 0.05)), pose_matrix((p[0], 0.0, p[2])))
    return k, CollisionModel(k, TOOL, [plate], clearance_m=0.0)


@settings(max_examples=30, deadline=None)
@given(a=st.floats(0.3, 0.8), b=st.floats(-0.2, 0.8))
def test_check_motion_never_misses_a_2mm_plate(a, b):
    k, world = _thin_plate_world(0.002)
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -a, b
    p0, p1 = k.T_world_tcp(q0)[:3, 3], k.T_world_tcp(q1)[:3, 3]
    assert np.sign(p0[1]) != np.sign(p1[1])  # the TCP crosses the plate's plane
    if not (world.is_valid(q0) and world.is_valid(q1)):
        return
    result = world.check_motion(q0, q1)
    assert not result.ok
    assert "plate" in result.clearance.b


def test_naive_sampling_would_miss_the_plate_the_check_finds():
    _k, world = _thin_plate_world(0.002)
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.5, 0.7
    samples = [q0 + s * (q1 - q0) for s in np.linspace(0, 1, 4)]
    assert all(world.is_valid(q) for q in samples)  # 0.4 rad samples step over the plate
    assert not world.check_motion(q0, q1).ok
    assert not world.check_path(np.array(samples)).ok


def test_free_motion_is_accepted_and_bound_is_sound():
    k, world = _thin_plate_world(0.002)
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = 0.2, 0.9
    assert world.check_motion(q0, q1).ok
    # the motion bound really bounds every point: the TCP moves less than the bound says
    dq = q1 - q0
    bound = world.bounds._reach[:, :] @ np.abs(dq)
    moved = np.linalg.norm(k.T_world_tcp(q1)[:3, 3] - k.T_world_tcp(q0)[:3, 3])
    assert moved <= bound.max() + 1e-12


def test_binary_stl_is_read(tmp_path):
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4")
    data = (
        bytearray(80)
        + np.uint32(1).tobytes()
        + np.zeros(3, "<f4").tobytes()
        + tri.tobytes()
        + bytes(2)
    )
    path = tmp_path / "t.stl"
    path.write_bytes(bytes(data))
    vertices, triangles = read_stl(path)
    assert vertices.shape == (3, 3) and triangles.shape == (1, 3)


def _sample_points(obj, rng, n=40):
    """Random points of an object's shape, in its parent joint's frame (T_joint_shape)."""
    import coal

    g = obj.geometry
    if obj.part is not None:  # a convex arm part: its vertices and points inside
        v = obj.part.vertices_m
        w = rng.dirichlet(np.full(len(v), 0.05), n)
        local = np.concatenate([v, w @ v])
    elif isinstance(g, (coal.Capsule, coal.Cylinder)):
        t = rng.uniform(-g.halfLength, g.halfLength, n)
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        if isinstance(g, coal.Cylinder):
            u[:, 2] = 0.0
            u /= np.maximum(np.linalg.norm(u, axis=1)[:, None], 1e-12)
        local = np.column_stack([np.zeros(n), np.zeros(n), t]) + g.radius * u
    elif isinstance(g, coal.Box):
        local = rng.uniform(-1, 1, (n, 3)) * np.asarray(g.halfSide)
        local[: min(n, 8)] = (
            np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])[: min(n, 8)]
            * g.halfSide
        )
    else:
        local = np.zeros((1, 3))
    T = obj.placement
    return local @ T[:3, :3].T + T[:3, 3]


def _cluttered_world(model: str = "ur5e"):
    fixtures = [
        Placed("table", Box((1.2, 1.2, 0.04)), pose_matrix((0, 0, -0.02))),
        Placed("post", Cylinder(0.03, 0.6), pose_matrix((0.4, 0.3, 0.3))),
    ]
    part = Placed("block", Box((0.05, 0.04, 0.06)), pose_matrix((0.01, 0, 0.03)))
    return CollisionModel(kin(model), TOOL, fixtures).carrying(part)


#: one world per arm model for the examples below: segment_bounds, motion_coefficients and
#: the object tables they read depend on q alone, never on a world's last query
_shared_world = functools.cache(_cluttered_world)


@pytest.mark.parametrize("model", available_models())
@settings(max_examples=25, deadline=None)
@given(
    q0=st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
    dq=st.lists(st.floats(-1.5, 1.5), min_size=6, max_size=6),
    pieces=st.integers(1, 4),
)
def test_segment_bounds_bound_the_motion_of_every_point(model, q0, dq, pieces):
    """Along a segment, no point of any object moves (relative to what it is checked
    against) faster than its pair's bound for that part of the segment says; on every arm
    model with derived geometry (each has its own parts, so its own bounds)."""
    world = _shared_world(model)
    q0, q1 = np.array(q0), np.array(q0) + np.array(dq)
    rates = world.segment_bounds(q0, q1, pieces)  # (pieces, pairs), per unit part
    static = world.motion_coefficients(q1 - q0)
    assert np.all(rates * pieces <= static + 1e-9)  # never looser than the static bound
    rng = np.random.default_rng(0)
    model = world.kinematics.model
    data = model.createData()
    steps = 24  # per part
    s = np.linspace(0.0, 1.0, pieces * steps + 1)
    frames = []
    for si in s:
        pin_fk(model, data, q0 + si * (q1 - q0))
        frames.append([data.oMi[j].homogeneous.copy() for j in range(7)])
    frames = np.array(frames)
    points = {
        k: _sample_points(o, rng) for k, o in enumerate(world._objects) if world.bounds._is_mover[k]
    }
    moved_by: dict[tuple[int, int], np.ndarray] = {}
    for p, (mover, high, joints) in enumerate(
        zip(
            world.bounds._pair_mover,
            world.bounds._pair_high,
            world.bounds._pair_joints,
            strict=True,
        )
    ):
        body = world.bounds._body[high]
        low = (
            0
            if world.bounds._pair_other_static[p]
            else int(
                min(world.bounds._body[mover], world.bounds._body[world.bounds._pair_other[p]])
            )
        )
        if (high, low) not in moved_by:  # pairs sharing the moving object and frame agree
            moved_by[high, low] = _largest_step(points[high], frames, body, low)
        for i in range(pieces):
            moved = float(moved_by[high, low][i * steps : (i + 1) * steps].max())
            # moved is over 1/steps of the part; the bound is for the whole part
            assert moved * steps <= rates[i, p] * (1 + 1e-6) + 1e-9, world.pair_labels[p]
        assert joints[:low].sum() == 0


def _largest_step(pts, frames, body, low):
    """Per step between consecutive frames (steps x 7 joint frames x 4 x 4): how far (m)
    the farthest of ``pts`` (fixed to ``body``) moves relative to body ``low``."""
    rel = np.linalg.inv(frames[:, low]) @ frames[:, body]  # (steps + 1, 4, 4)
    moved = pts @ rel[:, :3, :3].transpose(0, 2, 1) + rel[:, None, :3, 3]  # (steps + 1, P, 3)
    return np.linalg.norm(np.diff(moved, axis=0), axis=2).max(axis=1)


def pin_fk(model, data, q):
    import pinocchio as pin

    pin.forwardKinematics(model, data, q)


def test_knot_bounds_cut_the_distance_queries_of_a_long_move():
    """The per-part bounds prove a long free move with fewer exact distance queries than
    the configuration-independent bound would need (same answer)."""
    world = _cluttered_world()
    q0 = np.radians([0, -90, 90, -90, -90, 0])
    q1 = np.radians([150, -60, 60, -120, -90, 90])
    tight = world.check_motion(q0, q1)
    import cellrunner.planning.collision as collision

    saved = collision.KNOT_STEP_RAD
    collision.KNOT_STEP_RAD = 100.0  # one part: the whole segment
    try:
        loose = world.check_motion(q0, q1)
    finally:
        collision.KNOT_STEP_RAD = saved
    assert tight.ok and loose.ok
    assert tight.distance_queries < loose.distance_queries


def test_state_check_keeps_the_clearance_where_bounding_boxes_do_not_overlap():
    """is_valid culls pairs by bounding boxes first; a fixture 1 mm below the tool (boxes
    apart) still violates a 2 mm clearance, and 3 mm away it does not."""
    k = kin()
    p = k.T_world_tcp(HOME)[:3, 3]  # the tool tip points down at HOME
    for gap_m, valid in ((0.001, False), (0.0019, False), (0.003, True)):
        plate = Placed("plate", Box((0.3, 0.3, 0.02)), pose_matrix(p - [0, 0, 0.01 + gap_m]))
        world = CollisionModel(k, TOOL, [plate], clearance_m=0.002)
        assert world.is_valid(HOME) is valid, gap_m


@settings(max_examples=20, deadline=None)
@given(q=st.lists(st.floats(-3.2, 3.2), min_size=6, max_size=6))
def test_state_check_agrees_with_the_exact_distances(q):
    world = _cluttered_world()
    q = np.array(q)
    d = world._exact(np.arange(len(world._pairs))) if world._update(q) is None else None
    exact_valid = bool(np.all(d - world._required >= 1e-4 + 1e-9))
    if np.any(np.abs(d - world._required - 1e-4) < 1e-7):
        return  # on the boundary itself
    assert world.is_valid(q) == exact_valid


@settings(max_examples=30, deadline=None)
@given(q=st.lists(st.floats(-3.2, 3.2), min_size=6, max_size=6))
def test_knot_lower_bounds_never_exceed_the_exact_distances(q):
    world = _cluttered_world()
    q = np.array(q)
    _, lower = world.bounds.knots(q, q, 1)  # both knots at q
    world._update(q)
    exact = world._exact(np.arange(len(world._pairs)))
    assert np.all(lower <= exact[None, :] + 1e-12), world.pair_labels[
        int(np.argmax(lower[0] - exact))
    ]


def test_joint_frames_match_pinocchio():
    import pinocchio as pin

    world = _cluttered_world()
    rng = np.random.default_rng(3)
    q = rng.uniform(-3, 3, (5, 6))
    frames = world.joint_frames(q)
    model = world.kinematics.model
    data = model.createData()
    for n in range(5):
        pin.forwardKinematics(model, data, q[n])
        for j in range(7):
            assert np.allclose(frames[n, j], data.oMi[j].homogeneous, atol=1e-12)


def _write_stl_box(path, size):
    """A closed box as a binary STL (12 triangles), centred on the origin."""
    import itertools
    import struct

    hx, hy, hz = (s / 2 for s in size)
    v = [np.array([x, y, z]) for x, y, z in itertools.product((-hx, hx), (-hy, hy), (-hz, hz))]
    faces = [
        (0, 1, 3),
        (0, 3, 2),
        (4, 6, 7),
        (4, 7, 5),
        (0, 4, 5),
        (0, 5, 1),
        (2, 3, 7),
        (2, 7, 6),
        (0, 2, 6),
        (0, 6, 4),
        (1, 5, 7),
        (1, 7, 3),
    ]
    with open(path, "wb") as f:
        f.write(b"\0" * 80 + struct.pack("<I", len(faces)))
        for a, b, c in faces:
            f.write(struct.pack("<3f", 0, 0, 0))
            for k in (a, b, c):
                f.write(struct.pack("<3f", *v[k]))
            f.write(b"\0\0")


def test_stl_mesh_fixture_matches_the_same_box(tmp_path):
    from cellrunner.model import geometry
    from cellrunner.model.geometry import Box, Mesh, Placed
    from cellrunner.model.robots import ROBOTS
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.kinematics import ArmKinematics

    stl = tmp_path / "block.stl"
    _write_stl_box(stl, (0.2, 0.2, 0.2))
    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), geometry.pose_matrix((0, 0, 0.1)))
    pose = geometry.pose_matrix((0.45, 0.1, 0.3))
    as_mesh = CollisionModel(kin, fixtures=[Placed("block", Mesh(stl), pose)])
    as_box = CollisionModel(kin, fixtures=[Placed("block", Box((0.2, 0.2, 0.2)), pose)])
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        d_mesh, _, _b_mesh = as_mesh.min_distance(q)
        d_box, _, _ = as_box.min_distance(q)
        if d_box > 0:  # outside: the mesh surface and the box agree
            assert abs(d_mesh - d_box) < 1e-6, (d_mesh, d_box)
        assert (d_mesh > 0) == (d_box > 0) or d_box < 0


def test_derived_models_are_built_once_per_part_and_allowances():
    from cellrunner.model.geometry import Box, Placed, pose_matrix
    from cellrunner.model.robots import ROBOTS
    from cellrunner.planning.collision import CollisionModel, ContactAllowance
    from cellrunner.planning.kinematics import ArmKinematics

    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_matrix((0, 0, 0.15)))
    table = Placed("table", Box((1.0, 1.0, 0.04)), pose_matrix((0.4, 0, -0.03)))
    root = CollisionModel(kin, (), [table])
    part = Placed("block", Box((0.05, 0.05, 0.05)), pose_matrix((0, 0, 0.025)))
    again = Placed("block", Box((0.05, 0.05, 0.05)), pose_matrix((0, 0, 0.025)))  # read anew
    moved = Placed("block", Box((0.05, 0.05, 0.05)), pose_matrix((0, 0, 0.030)))
    held = root.carrying(part)
    assert root.carrying(again) is held
    assert root.carrying(moved) is not held
    assert held.carrying(None) is root.carrying(None)
    allowed = held.allowing(ContactAllowance("table", "part", -0.001))
    assert allowed is root.carrying(again).allowing(ContactAllowance("table", "part", -0.001))
    assert allowed.part is part and allowed.allowances == (
        ContactAllowance("table", "part", -0.001),
    )
    assert allowed.allowing() is held
    # the cached models answer as fresh ones do
    fresh = CollisionModel(kin, (), [table], part=moved)
    q = np.radians([0, -90, 90, -90, -90, 0])
    assert root.carrying(moved).min_distance(q)[0] == fresh.min_distance(q)[0]
