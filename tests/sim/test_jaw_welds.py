"""The twin's jaws hold a part where it was gripped, as a real pad's friction does, and
let go when they open (issue 33: MuJoCo's velocity-level friction let a carried pin creep
1-2 mm across the pads and onto the rim of its hole)."""

from __future__ import annotations

import math

import numpy as np

from cellrunner.sim import demo
from cellrunner.sim.jaw_welds import PAD_CONDIM


def _pose_in_jaws(driver) -> tuple[np.ndarray, np.ndarray]:
    T = driver.backend.world.contacts.part_in_tcp("cube")
    return T[:3, 3].copy(), T[:3, :3].copy()


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    c = (float(np.trace(R_a.T @ R_b)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def test_a_part_swung_fast_stays_where_the_jaws_gripped_it(driver) -> None:
    driver.pick_cube()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.15), 0.6, "lift")
    p0, R0 = _pose_in_jaws(driver)
    world = driver.backend.world
    assert world.jaw_welds.held == {"cube"}
    pads = [int(g) for g in world.ids.pad_geoms]
    assert list(world.model.geom_condim[pads]) == [1, 1]  # the weld holds, not friction
    q_far = driver.q + np.array([1.6, 0.0, 0.0, 0.0, 0.0, 0.0])  # the base swung and back
    q_back = driver.q.copy()
    for _ in range(2):
        driver.move_joints(q_far, 0.7, "swing")
        driver.move_joints(q_back, 0.7, "swing back")
    p1, R1 = _pose_in_jaws(driver)
    assert float(np.linalg.norm(p1 - p0)) < 2e-4  # m
    assert _angle_deg(R0, R1) < 0.2


def test_opening_the_jaws_lets_go_and_gives_the_pads_their_friction_back(driver) -> None:
    driver.pick_cube()
    world = driver.backend.world
    assert world.jaw_welds.held == {"cube"}
    driver.backend.set_output("DO0", False)
    driver.wait(0.6)
    assert world.jaw_welds.held == set()
    pads = [int(g) for g in world.ids.pad_geoms]
    assert list(world.model.geom_condim[pads]) == [PAD_CONDIM, PAD_CONDIM]
    resting = world.part_pose_world("cube")[:3, 3].copy()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.12), 0.8, "retreat")
    assert float(np.linalg.norm(world.part_pose_world("cube")[:3, 3] - resting)) < 1e-3
