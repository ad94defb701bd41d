"""The obstacle map: hits where depth rays end, misses where they pass (stale voxels
clear), the cell file's own things never occupied, and a twin intrusion found where it is."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.errors import UsageError
from cellrunner.model.load import load_cell
from cellrunner.perception.frames import DepthFrame
from cellrunner.perception.known import KnownScene
from cellrunner.perception.occupancy import OccupancyMap
from cellrunner.perception.path_check import first_blocked
from cellrunner.perception.solids import near_any
from cellrunner.planning.world import CellWorld
from tests.conftest import ROOT

WATCHED = ROOT / "cells" / "watched_ur5e.yaml"
K = np.array([[100.0, 0, 49.5], [0, 100.0, 39.5], [0, 0, 1]])
#: a camera 2 m above the world origin looking straight down (OpenCV frame: Z down)
T_WORLD_CAMERA = np.array([[1.0, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 2.0], [0, 0, 0, 1]])


def plane_frame(depth_m: float, box_top_m: float | None = None) -> DepthFrame:
    """A 100 x 80 image of a floor ``depth_m`` away, with a box's top in the middle."""
    depth = np.full((80, 100), depth_m, np.float32)
    if box_top_m is not None:
        depth[30:50, 40:60] = box_top_m
    return DepthFrame("top", 0.0, depth, T_WORLD_CAMERA, K)


def test_a_box_is_hit_where_its_rays_end_and_cleared_once_it_is_gone():
    m = OccupancyMap(_zone(0.5), (1.0, 1.0, 1.0), 0.02)
    update = m.integrate(plane_frame(2.0, box_top_m=1.59), (0.3, 2.5))
    centres = m.occupied_centres()
    assert update.hits == len(centres) > 0
    # the box's top lies 0.41 m above the floor (z = 0) and under the middle of the image
    assert np.allclose(centres[:, 2], 0.41, atol=0.011)
    assert np.abs(centres[:, :2]).max() < 0.2
    # the floor (z = 0) lies outside the zone (0 < z < 1): never a hit
    for _ in range(8):
        m.integrate(plane_frame(2.0, box_top_m=1.59), (0.3, 2.5))
    assert len(m.occupied()) == len(centres)
    cleared_after = next(
        k for k in range(1, 30) if m.integrate(plane_frame(2.0), (0.3, 2.5)).occupied == 0
    )
    assert 8 <= cleared_after <= 10  # from the 0.97 clamp by 0.4 misses: nine images


def test_out_of_range_depths_and_lone_points_are_no_hits():
    m = OccupancyMap(_zone(0.5), (1.0, 1.0, 1.0), 0.02)
    far = plane_frame(2.0, box_top_m=1.59)
    assert m.integrate(far, (0.3, 1.5)).hits == 0  # the box's top is beyond 1.5 m
    depth = np.full((80, 100), 2.0, np.float32)
    depth[40, 50] = 1.5  # a flying pixel
    assert m.integrate(DepthFrame("top", 0.0, depth, T_WORLD_CAMERA, K), (0.3, 2.5)).hits == 0


def test_a_snapshot_reads_back_the_same_map(tmp_path):
    m = OccupancyMap(_zone(0.5), (1.0, 1.0, 1.0), 0.02)
    m.integrate(plane_frame(2.0, box_top_m=1.59), (0.3, 2.5))
    m.save(tmp_path / "map.npz")
    back = OccupancyMap.load(tmp_path / "map.npz")
    assert np.array_equal(back.occupied(), m.occupied()) and back.voxel_m == 0.02
    (tmp_path / "bad.npz").write_bytes(b"nope")
    with pytest.raises(UsageError, match="not a map snapshot"):
        OccupancyMap.load(tmp_path / "bad.npz")


def _zone(z_m: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z_m
    return T


@pytest.fixture(scope="module")
def watched():
    loaded = load_cell(WATCHED)
    world = CellWorld(loaded)
    return loaded, world, KnownScene(world)


def twin_map(loaded, known):
    watch = loaded.cell.watch
    m = OccupancyMap(watch.zone.pose.matrix(), tuple(watch.zone.box.size), watch.voxel)
    pad = watch.padding + m.half_diagonal_m
    static = known.static_solids()
    m.mark_known(lambda c: near_any(static, c, pad), known.static_surfaces(watch.voxel / 2), pad)
    return m, pad


def test_the_twin_static_cell_leaves_the_map_empty_and_a_dropped_box_is_found(watched):
    from cellrunner.sim.depth import DepthImager
    from cellrunner.sim.from_cell import description_of
    from cellrunner.sim.world import SimWorld

    loaded, _, known = watched
    description = description_of(loaded)
    world = SimWorld(description)
    world.build()
    imager = DepthImager(world.model, description.cameras[0], (0.3, 2.5), 0.002, use_gl=False)
    m, pad = twin_map(loaded, known)

    def look():
        frame = imager.frame(world.data.qpos, world.data.mocap_pos, world.data.mocap_quat, 0.0)
        robot = known.robot_at(frame.q_rad)
        return m.integrate(frame, (0.3, 2.5), lambda c: near_any(robot, c, pad))

    for _ in range(3):
        assert look().occupied == 0  # the arm, tool, table, column and block: all known
    box = np.eye(4)
    box[:3, 3] = (0.55, 0.25, 0.98)  # on the table, 12 cm cube: top at 1.04 m
    assert world.intruders.inject(box, world.time_s) == "intrusion"
    world.step_period()
    update = look()
    assert update.occupied > 0
    centres = m.occupied_centres()
    assert np.abs(centres[:, :2] - (0.55, 0.25)).max() < 0.09
    assert centres[:, 2].max() < 1.06


def test_a_path_through_a_box_is_blocked_where_it_meets_it(watched):
    _, world, known = watched
    q0 = world.q_home_rad
    q1 = q0 + np.radians([40, 0, 0, 0, 0, 0])
    path = q0 + np.linspace(0, 1, 200)[:, None] * (q1 - q0)
    tcp = world.kinematics.p_world_tcp(path[120])
    box = tcp + np.array([[dx, dy, 0.0] for dx in (-0.02, 0, 0.02) for dy in (-0.02, 0, 0.02)])
    blocked = first_blocked(known, path, box, 0.03 + 0.0173)
    # the open finger pads (ahead of the TCP on the arc) meet it first, before the TCP would
    assert blocked is not None and 20 < blocked.index < 120
    beside = box + np.array([0.0, 0.0, 0.5])  # half a metre above the whole sweep
    assert first_blocked(known, path, beside, 0.03 + 0.0173) is None
