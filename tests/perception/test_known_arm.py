"""The watch explains the arm the twin draws, for every arm: each convex part's solid holds
the whole part (the UR10's forearm was cut by a sliver triangle's plane, and a watched
UR10 cell stopped its own arm at home: 108, issue 33)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cellrunner.model.arm_geometry import arm_geometry, available_models
from cellrunner.perception.known import arm_solids


@pytest.mark.parametrize("model", available_models())
def test_every_arm_part_solid_holds_all_its_vertices(model):
    parts = arm_geometry(model).parts
    solids = arm_solids(model)
    assert len(solids) == len(parts)
    for part, placed in zip(parts, solids, strict=True):
        assert placed.body == part.body
        solid = placed.solid
        assert solid.planes is not None
        outside_m = part.vertices_m @ solid.planes[:, :3].T - solid.planes[:, 3]
        assert outside_m.max() < 1e-9, (part.link, part.index, outside_m.max())
        # and nothing past the part: 1 mm beyond each side of its box is outside
        lo, hi = part.vertices_m.min(axis=0), part.vertices_m.max(axis=0)
        centre = (lo + hi) / 2
        beyond = np.vstack(
            [centre + np.diag(hi - centre + 0.001), centre - np.diag(centre - lo + 0.001)]
        )
        assert not solid.near(beyond, 0.0).any(), (part.link, part.index)


#: the generator's s60075 as it was written when the watch saw the arm itself (the
#: generator draws other cells from that seed since), and its witnesses (deg)
DATA = Path(__file__).resolve().parent.parent / "data" / "watched_ur10"
WITNESS_DEG = {
    "pick": [56.446, -193.217, 109.855, -186.637, -90.0, -98.994],
    "place": [60.904, -56.635, 59.22, 87.415, -90.0, 54.552],
}


def test_a_watched_ur10_on_the_ceiling_sees_nothing_but_itself_in_the_twin():
    """Generated seed 60075: a UR10 hanging from the ceiling under a fixed depth camera;
    at home and at its pick and place witnesses every voxel the camera hits is explained
    by the cell file."""
    from cellrunner.model.load import load_cell
    from cellrunner.perception.known import KnownScene
    from cellrunner.perception.occupancy import OccupancyMap
    from cellrunner.perception.solids import near_any
    from cellrunner.planning.world import CellWorld
    from cellrunner.sim.depth import DepthImager
    from cellrunner.sim.from_cell import description_of
    from cellrunner.sim.world import SimWorld

    loaded = load_cell(DATA / "cell.yaml")
    assert loaded.cell.robot.model == "ur10"
    world = CellWorld(loaded)
    known = KnownScene(world)
    watch = loaded.cell.watch
    assert watch is not None
    description = description_of(loaded)
    sim = SimWorld(description)
    sim.build()
    camera = description.cameras[0]
    range_m = loaded.cell.cameras[camera.name].depth.range_m
    imager = DepthImager(sim.model, camera, range_m, 0.0, use_gl=False)
    poses = {"home": world.q_home_rad}
    poses.update({name: np.radians(q) for name, q in WITNESS_DEG.items()})
    assert len(poses) == 3
    static = known.static_solids()
    surfaces = known.static_surfaces(watch.voxel / 2)

    def look(q: np.ndarray):
        """A fresh map of the zone after one image of the twin with the arm at ``q``."""
        m = OccupancyMap(watch.zone.pose.matrix(), tuple(watch.zone.box.size), watch.voxel)
        pad = watch.padding + m.half_diagonal_m
        m.mark_known(lambda c: near_any(static, c, pad), surfaces, pad)
        qpos = np.array(sim.data.qpos)
        qpos[:6] = q
        frame = imager.frame(qpos, sim.data.mocap_pos, sim.data.mocap_quat, 0.0)
        robot = known.robot_at(frame.q_rad)
        return m, m.integrate(frame, range_m, lambda c: near_any(robot, c, pad))

    for name, q in poses.items():
        m, update = look(q)
        assert update.misses > 0, name  # the camera sees the zone
        assert update.occupied == 0, (name, m.occupied_centres())
