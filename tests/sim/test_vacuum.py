"""Suction in the MuJoCo twin: a cup seals on a face, the weld holds the part while the
pull stays under the holding force, suction off or blow-off drops it, a tilted cup does
not seal; everything seen through vacuum_ok and the wrist, as the engine sees it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cellrunner.model import geometry
from cellrunner.model.expand import frame_pose
from cellrunner.model.load import load_cell
from tests.conftest import ROOT

CELL = ROOT / "cells" / "palletizer_ur10e.yaml"
VACUUM_ON, BLOW_OFF, VACUUM_OK = "DO0", "DO1", "DI0"


def build(holding_force_N: float | None = None, cell=CELL):
    from cellrunner.planning.world import CellWorld
    from cellrunner.sim.from_cell import description_of
    from cellrunner.sim.world import SimWorld

    loaded = load_cell(cell)
    desc = description_of(loaded)
    if holding_force_N is not None:
        desc = dataclasses.replace(
            desc, vacuum=dataclasses.replace(desc.vacuum, holding_force_N=holding_force_N)
        )
    world = SimWorld(desc)
    world.build()
    return world, CellWorld(loaded), loaded


def put_tcp(world, cell_world, T_world_tcp) -> np.ndarray:
    """Stand the arm (at rest) with its TCP at ``T_world_tcp``, on a branch clear of the
    fixtures (the carton waiting under the cups is what they are put on)."""
    from cellrunner.planning.collision import CollisionModel

    fixtures_only = CollisionModel(cell_world.kinematics, cell_world.tool, cell_world.fixtures)
    q = next(
        q
        for q in cell_world.kinematics.ik_all(T_world_tcp, world.q_measured())
        if fixtures_only.is_valid(q)
    )
    world.place_arm(q)
    return q


def move_tcp(world, cell_world, T_to, duration_s: float) -> None:
    """A straight joint-space move to ``T_to`` (slow enough for the servo to follow)."""
    q0 = world.q_measured()
    q1 = cell_world.kinematics.ik_nearest(T_to, q0)
    n = int(duration_s * world.description.rate_hz)
    for i in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * i / n)
        world.command(q0 + s * (q1 - q0), np.zeros(6))
        world.step_period()


def settle(world, seconds: float) -> None:
    for _ in range(int(seconds * world.description.rate_hz)):
        world.step_period()


def grip_and_lift(
    world, kin, loaded, lift_m: float = 0.1, tilt_deg: float = 0.0, above_m: float = 0.001
) -> tuple[float, float]:
    """TCP ``above_m`` over the carton's top face, suction on, lift; (carton rise m, wrist load N)."""
    T = (
        geometry.pose_matrix((0, 0, above_m))
        @ frame_pose(loaded.cell, "infeed")
        @ geometry.pose_matrix((0, 0, 0), (tilt_deg, 0, 0))
    )
    put_tcp(world, kin, T)
    settle(world, 0.2)
    world.zero_ft_sensor()
    z0 = world.part_pose_world("carton")[2, 3]
    world.set_output(VACUUM_ON, True)
    settle(world, 0.1)
    move_tcp(world, kin, geometry.pose_matrix((0, 0, lift_m)) @ T, 1.0)
    settle(world, 0.3)
    load = float(np.linalg.norm(world.measure().wrench_N[:3]))
    return world.part_pose_world("carton")[2, 3] - z0, load


def test_cups_seal_and_hold_the_carton():
    world, kin, loaded = build()
    rise, load = grip_and_lift(world, kin, loaded)
    assert rise == pytest.approx(0.1, abs=0.004)
    assert load == pytest.approx(2.0 * 9.81, rel=0.05)  # the carton's weight at the wrist
    assert world.measure().inputs[VACUUM_OK] is True


def test_a_pull_above_the_holding_force_tears_the_carton_off():
    world, kin, loaded = build(holding_force_N=12.0)  # under the carton's 19.6 N weight
    rise, load = grip_and_lift(world, kin, loaded)
    assert rise < 0.01
    assert load < 1.0
    assert world.measure().inputs[VACUUM_OK] is False


def test_suction_off_drops_the_carton_and_blow_off_breaks_the_seal():
    world, kin, loaded = build()
    grip_and_lift(world, kin, loaded)
    world.set_output(VACUUM_ON, False)
    settle(world, 0.5)
    assert world.part_pose_world("carton")[2, 3] == pytest.approx(
        0.65, abs=0.003
    )  # back on the conveyor
    assert world.measure().inputs[VACUUM_OK] is False
    world, kin, loaded = build()
    grip_and_lift(world, kin, loaded)
    world.set_output(BLOW_OFF, True)  # suction still on
    settle(world, 0.5)
    assert world.part_pose_world("carton")[2, 3] == pytest.approx(0.65, abs=0.003)
    assert world.measure().inputs[VACUUM_OK] is False


def rim_over_face_m(tilt_deg: float) -> float:
    """TCP height over the face that puts the lowest cup's rim 0.5 mm over it."""
    return (0.045 + 0.02) * np.sin(np.radians(tilt_deg)) + 0.0005


def test_a_tilted_cup_does_not_seal():
    world, kin, loaded = build()  # 5 deg off square seals (a seal allows 10 deg) ...
    rise, _ = grip_and_lift(world, kin, loaded, tilt_deg=5.0, above_m=rim_over_face_m(5.0))
    assert rise > 0.09
    world, kin, loaded = build()  # ... 25 deg does not
    rise, _ = grip_and_lift(world, kin, loaded, tilt_deg=25.0, above_m=rim_over_face_m(25.0))
    assert rise < 0.01
    assert world.measure().inputs[VACUUM_OK] is False


def test_grip_miss_leaves_the_cups_on_nothing():
    world, kin, loaded = build()
    world.inject_fault("grip_miss")
    rise, load = grip_and_lift(world, kin, loaded)
    assert rise < 0.01 and load < 1.0
    assert world.measure().inputs[VACUUM_OK] is False


def test_grip_miss_takes_a_tall_carton_away_from_the_cups(tmp_path):
    """A 200 mm carton: its centre 100 mm under the cups (the fault once looked for a
    centre nearer than that and left it sealed). Moved clear of all four cups."""
    tall = tmp_path / "tall.yaml"
    tall.write_text(
        CELL.read_text()
        .replace("size: [0.20, 0.15, 0.10]}, mass: 2.0", "size: [0.20, 0.15, 0.20]}, mass: 3.0")
        .replace("xyz: [0.15, -0.70, 0.70]", "xyz: [0.15, -0.70, 0.80]")
    )
    world, kin, loaded = build(cell=tall)
    x0, y0 = world.part_pose_world("carton")[:2, 3]
    world.inject_fault("grip_miss")
    rise, load = grip_and_lift(world, kin, loaded)
    assert rise < 0.01 and load < 1.0
    assert world.measure().inputs[VACUUM_OK] is False
    x, y = world.part_pose_world("carton")[:2, 3]
    assert np.hypot(x - x0, y - y0) > 0.2  # its 125 mm half-diagonal plus the cups' 95 mm


def test_a_carton_held_by_suction_pushed_into_the_conveyor_is_a_protective_stop():
    """Set back down on the conveyor and driven 30 mm on: a contact, as for jaws."""
    from cellrunner.errors import BackendError
    from cellrunner.model.robot_state import Safety

    world, kin, loaded = build()
    grip_and_lift(world, kin, loaded, lift_m=0.05)
    T_down = geometry.pose_matrix((0, 0, -0.03)) @ frame_pose(loaded.cell, "infeed")
    with pytest.raises(BackendError, match="safety state is protective_stop"):
        move_tcp(world, kin, T_down, 1.5)
    assert world.safety is Safety.PROTECTIVE_STOP
    # judged on the carton against the conveyor, over the force UR stops at
    assert set(world.last_contact.geoms) == {"fixture:conveyor", "part:carton"}
    assert world.last_contact.force_N > 150.0


def test_a_carton_set_down_by_suction_and_released_is_measured_against_its_target():
    world, kin, loaded = build()
    grip_and_lift(world, kin, loaded, lift_m=0.05)
    T_high = geometry.pose_matrix((0, 0, 0.04)) @ frame_pose(loaded.cell, "infeed")
    move_tcp(world, kin, T_high, 1.0)  # 40 mm above where it was picked
    world.set_output(VACUUM_ON, False)
    settle(world, 0.5)
    found = world.inspect_place(T_high)
    assert found.part == "carton"
    assert found.offset_m == pytest.approx(0.041, abs=0.003)  # fell 41 mm, measured at rest
    assert found.judged_m == pytest.approx(0.041 - 0.01, abs=0.003)  # 10 mm are free
    assert found.angle_deg < 1.0 and found.resting_on == "fixture"
    found = world.inspect_place(frame_pose(loaded.cell, "infeed"))
    assert found.offset_m < 0.002  # back where the TCP picked it
