"""The twin's feed (``sim: feed``, SPEC section 12): a new part at its frame before each
job unless one lies there; in the virtual controller, once the part fed last was taken
away; and the cell file's reference to it checked like any other."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.errors import InputError
from cellrunner.model.load import load_cell
from tests.conftest import ROOT

CELL = (ROOT / "cells" / "palletizer_ur10e.yaml").read_text()
FEED = "sim:\n  feed: {part: carton, at: infeed}\n"


def fed_world(tmp_path, feed: str = FEED):
    from cellrunner.sim.from_cell import description_of
    from cellrunner.sim.world import SimWorld

    path = tmp_path / "cell.yaml"
    path.write_text(CELL.replace("sim:\n", feed))
    world = SimWorld(description_of(load_cell(path), feed_copies=2))
    world.build()
    return world


def carry_away(world, name: str) -> None:
    """The part leaves the spot (a job took it), and the physics catches up."""
    adr = world.ids.part_qpos[name]
    world.data.qpos[adr : adr + 3] = (0.8, 0.2, 0.3)  # on the pallet
    for _ in range(50):
        world.step_period()


def test_a_part_is_fed_only_where_the_spot_is_empty(tmp_path):
    world = fed_world(tmp_path)
    spot = world.part_pose_world("carton")[:3, 3].copy()
    assert world.feed_parts() == []  # the cell file's carton is there
    carry_away(world, "carton")
    parked = world.part_pose_world("carton#2")[:3, 3].copy()
    assert world.feed_parts() == ["carton#1"]
    assert np.linalg.norm(world.part_pose_world("carton#1")[:3, 3] - spot) < 1e-6
    for _ in range(250):  # 0.5 s: the fed copy rests on the conveyor (it collides and
        world.step_period()  # weighs again), the parked one floats where it was
    assert np.linalg.norm(world.part_pose_world("carton#1")[:3, 3] - spot) < 0.002
    assert np.linalg.norm(world.part_pose_world("carton#2")[:3, 3] - parked) < 1e-6
    assert world.feed_parts() == []
    carry_away(world, "carton#1")
    assert world.feed_parts() == ["carton#2"]
    carry_away(world, "carton#2")
    assert world.feed_parts() == ["carton#1"]  # every copy out: the oldest comes back
    np.testing.assert_allclose(world.part_pose_world("carton")[:3, 3], (0.8, 0.2, 0.3), atol=0.2)


def test_the_virtual_controller_feeds_once_the_part_was_taken(tmp_path):
    world = fed_world(tmp_path)
    carry_away(world, "carton")  # pushed off (a grip_miss): never gripped, not replaced
    assert world.feeder.update() is None
    world._gripped = frozenset({"carton"})  # the cups took it (as the physics would say) ...
    assert world.feeder.update() is None
    world._gripped = frozenset()  # ... and let go of it elsewhere
    assert world.feeder.update() == "carton#1"


def test_the_feed_names_a_part_and_a_frame_of_the_cell(tmp_path):
    path = tmp_path / "cell.yaml"
    path.write_text(CELL.replace("sim:\n", "sim:\n  feed: {part: cartn, at: infed}\n"))
    with pytest.raises(InputError) as exc:
        load_cell(path)
    text = [str(d) for d in exc.value.diagnostics]
    assert any("unknown part 'cartn' (did you mean 'carton'?)" in t for t in text), text
    assert any("unknown frame 'infed' (did you mean 'infeed'?)" in t for t in text), text
