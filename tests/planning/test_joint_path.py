"""Joint paths: direct or searched, certified edges, rounded corners."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cellrunner.planning.collision as collision_module
from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix
from cellrunner.model.robots import ROBOTS
from cellrunner.planning.collision import CollisionModel, MotionCheck
from cellrunner.planning.joint_path import CORNER_POINTS, plan_joint_path, round_corners
from cellrunner.planning.kinematics import ArmKinematics
from tests.planning.pins import pin_between_samples

TOOL = (Placed("gripper", Cylinder(0.04, 0.15), pose_matrix((0, 0, 0.075))),)
HOME = np.radians([0, -90, 90, -90, -90, 0])


def _world():
    """A low wall on a table between two pick poses (as bench/scenes.py's table scene)."""
    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_matrix((0, 0, 0.15)))
    fixtures = [
        Placed("table", Box((1.6, 1.6, 0.04)), pose_matrix((0, 0, -0.02))),
        Placed("wall", Box((0.4, 0.03, 0.30)), pose_matrix((0.50, 0.0, 0.15))),
    ]
    return CollisionModel(kin, TOOL, fixtures)


def _targets(world):
    kin = world.kinematics
    down, near = (180.0, 0.0, 0.0), np.radians([180, -90, 90, -90, -90, 0])
    a = kin.ik_nearest(pose_matrix((0.45, -0.25, 0.06), down), near)
    b = kin.ik_nearest(pose_matrix((0.45, 0.25, 0.06), down), near)
    return a, b


def test_path_around_a_wall_is_certified_and_rounded():
    world = _world()
    a, b = _targets(world)
    assert not world.check_motion(a, b).ok  # the wall is in the way
    path = plan_joint_path(world, a, b, seed=1)
    assert path.planner == "rrtconnect"
    assert np.allclose(path.q_rad[0], a) and np.allclose(path.q_rad[-1], b)
    for p, q in zip(path.q_rad[:-1], path.q_rad[1:], strict=True):
        assert world.check_motion(p, q).ok  # every edge, arcs included, proven
    assert len(path.q_rad) >= 2 + CORNER_POINTS  # at least one corner became an arc


def test_round_corners_keeps_a_corner_no_arc_clears(monkeypatch):
    world = _world()
    q = np.array([HOME, HOME + [0.5, 0, 0, 0, 0, 0], HOME + [0.5, 0.3, 0, 0, 0, 0]])
    monkeypatch.setattr(CollisionModel, "check_path", lambda self, q: MotionCheck(False, 0.0))
    assert np.array_equal(round_corners(world, q), q)


def test_round_corners_never_lengthens_the_path():
    world = _world()
    q = np.array([HOME, HOME + [0.8, 0, 0, 0, 0, 0], HOME + [0.8, 0.4, -0.3, 0, 0, 0]])
    rounded = round_corners(world, q)
    length = lambda p: float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())  # noqa: E731
    assert length(rounded) <= length(q) + 1e-12
    assert world.check_path(rounded).ok


@settings(max_examples=25, deadline=None)
@given(
    start=st.lists(st.floats(-2.5, 2.5), min_size=6, max_size=6),
    steps=st.lists(st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6), min_size=1, max_size=6),
)
def test_check_path_lower_bound_pruning_changes_no_verdict(start, steps):
    world = _world()
    q = np.cumsum(np.vstack([start, steps]), axis=0)
    saved = collision_module.PATH_CHUNK_BOUNDS
    verdicts = []
    for chunked in (False, True):  # every pair by its reach, then by the chunks' bounds
        collision_module.PATH_CHUNK_BOUNDS = chunked
        try:
            verdicts.append(world.check_path(q).ok)
        finally:
            collision_module.PATH_CHUNK_BOUNDS = saved
    assert verdicts[0] == verdicts[1]


@settings(max_examples=30, deadline=None)
@given(
    start=st.lists(st.floats(-2.5, 2.5), min_size=6, max_size=6),
    turn=st.lists(st.floats(-1.2, 1.2), min_size=6, max_size=6),
    samples=st.integers(60, 400),
)
def test_check_path_on_dense_samples_agrees_with_every_segment_checked_alone(start, turn, samples):
    """The verifier's shared-query schedule (pairs measured at shared samples, horizons
    from the summed bounds) accepts exactly the dense polylines whose every segment
    ``check_motion`` proves on its own, and rejects the others."""
    world = _world()
    s = np.linspace(0.0, 1.0, samples) ** 2  # uneven spacing, as a timed trajectory
    q = np.asarray(start) + s[:, None] * np.asarray(turn) + 0.1 * np.sin(3 * s)[:, None]
    result = world.check_path(q)
    alone = all(world.check_motion(a, b, probe=False).ok for a, b in itertools.pairwise(q))
    assert result.ok == alone
    if not result.ok:  # the reported place is a sample or a point between two
        assert 0.0 <= result.s_blocked <= samples - 1
        assert not world.check_path(q[: int(result.s_blocked) + 2]).ok


def test_a_plate_the_sampled_shortcut_steps_over_is_caught_by_the_proofs(monkeypatch):
    """Shortening samples its edges; a shortcut across a 2 mm plate that the samples step
    over is caught by the proofs after (of the arcs and the straight pieces between them):
    the planner falls back to proving while shortening, and every piece of what it returns
    is proven."""
    import cellrunner.planning.joint_path as joint_path

    kin = ArmKinematics(ROBOTS["ur5e"], np.eye(4), pose_matrix((0, 0, 0.15)))
    p = kin.T_world_tcp(HOME)[:3, 3]
    plate = Placed("plate", Box((0.4, 0.002, 0.05)), pose_matrix((p[0], 0.0, p[2])))
    world = CollisionModel(kin, TOOL, [plate], clearance_m=0.0)
    # a search result whose shortcut a -> m2 crosses the plate (the tool at y = 0 near
    # joint 1 = -0.26 rad), its own edges going over it
    a, m1, m2, b = (HOME + np.array([j1, 0, 0, 0, 0, 0]) for j1 in (-0.5, -0.5, 0.7, 0.7))
    m1[1] -= 0.6  # raised over the plate
    b[2] += 0.2
    lazy = np.array([a, m1, m2, b])
    assert not world.check_motion(a, m2).ok
    monkeypatch.setattr(joint_path, "LAZY_RESOLUTION_RAD", 1.0)  # samples step over it
    assert joint_path.sampled_free(world, a, m2)
    assert joint_path._shorten_sampled_then_prove(world, lazy) is None

    real_search = joint_path._rrt_connect
    monkeypatch.setattr(
        joint_path,
        "_rrt_connect",
        lambda *args, conservative: real_search(*args, conservative=True) if conservative else lazy,
    )
    path = plan_joint_path(world, a, b, seed=1)
    assert len(path.q_rad) > 2
    for q0, q1 in zip(path.q_rad[:-1], path.q_rad[1:], strict=True):
        assert world.check_motion(q0, q1).ok


@pytest.mark.parametrize("model", ["ur5e", "ur5", "ur10e", "ur20"])
def test_a_sampled_path_is_marked_so_and_a_proven_one_clears_what_sampling_missed(model):
    """A 2 mm pin 3 mm inside the tool's rim halfway between two samples of a turn of the
    base: ``proven=False`` samples the straight move as free (and says it is not proven);
    the default proves every piece and goes round."""
    kin = ArmKinematics(ROBOTS[model], np.eye(4), pose_matrix((0, 0, 0.15)))
    a, b = HOME, HOME + np.radians([90, 0, 0, 0, 0, 0])
    xyz = pin_between_samples(kin, a, b, 0.075, 0.04)  # TOOL's cylinder
    pin = Placed("pin", Box((0.002, 0.002, 0.002)), pose_matrix(tuple(xyz)))
    world = CollisionModel(kin, TOOL, [pin])
    sampled = plan_joint_path(world, a, b, proven=False)
    assert (sampled.planner, sampled.proven) == ("direct", False)
    assert not world.check_path(sampled.q_rad).ok
    proven = plan_joint_path(world, a, b)
    assert proven.proven and proven.planner == "rrtconnect"
    assert world.check_path(proven.q_rad).ok
