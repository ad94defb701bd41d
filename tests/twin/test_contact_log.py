"""A contact the MuJoCo twin stops on is named in the virtual controller's log: which
geoms, how hard and when (a protective stop's cause, for whoever reads the twin's log)."""

from __future__ import annotations

import dataclasses

import numpy as np

from cellrunner.model.geometry import Box, Placed, pose_matrix
from cellrunner.model.load import load_cell
from cellrunner.planning.world import CellWorld
from cellrunner.sim.from_cell import description_of
from tests.conftest import DEMO_CELL


def test_the_contact_a_twin_stops_on_is_named():
    from cellrunner.twin.mujoco_physics import MujocoPhysics

    cell = load_cell(DEMO_CELL)
    description = description_of(cell)
    world = CellWorld(cell)
    q0 = world.q_home_rad
    turn = np.array([0.4, 0, 0, 0, 0, 0])  # the shoulder pans 0.4 rad: into the box
    at = world.kinematics.p_world_tcp(q0 + turn)
    box = Placed("obstacle", Box((0.15, 0.15, 0.15)), pose_matrix(tuple(at)))
    physics = MujocoPhysics(dataclasses.replace(description, fixtures=(*description.fixtures, box)))
    physics.reset(q0)
    for k in range(1, 1001):  # 0.5 rad/s, 2 s at most
        physics.step(q0 + turn * min(k / 400, 1.0), 0.002)
        measured = physics.measure()
        if measured.contact:
            break
    assert measured.contact
    assert "against" in measured.contact_what and "obstacle" in measured.contact_what
    force_N = float(measured.contact_what.split(", ")[1].split(" N")[0])
    assert force_N > description.contact_force_limit_N
