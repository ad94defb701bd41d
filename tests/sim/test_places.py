"""Places in the twin: a part set down is inspected against its target, and a carried
part forced into a fixture is a contact (SPEC section 11)."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.errors import BackendError
from cellrunner.model.robot_state import Safety
from cellrunner.sim import demo
from cellrunner.sim.places import PLACE_DROP_M

TABLE_SPOT = np.array((0.30, 0.15, demo.CUBE_XYZ_M[2]))  # free table, where the cube may go


def _carry_to(driver, xyz) -> None:
    driver.pick_cube()
    driver.move_tcp(np.array(demo.CUBE_XYZ_M) + (0, 0, 0.15), 1.0, "lift")
    driver.move_tcp(np.array(xyz) + (0, 0, 0.10), 1.5, "approach")


def _release(driver) -> None:
    driver.backend.set_output("DO0", False)
    driver.wait(0.6)


def test_a_part_set_down_where_it_was_sent_is_within_a_millimetre(driver) -> None:
    _carry_to(driver, TABLE_SPOT)
    target = TABLE_SPOT + (0, 0, 0.005)  # the grasp height of the pick
    driver.move_tcp(target, 1.0, "descend")
    _release(driver)
    driver.move_tcp(target + (0, 0, 0.1), 0.8, "retreat")
    found = driver.backend.inspect_place(demo.tcp_down_at(target))
    assert found.part == "cube" and found.resting_on == "fixture"
    assert found.offset_m < 0.002 and found.angle_deg < 1.0


def test_a_part_dropped_from_above_its_target_is_off_by_the_whole_fall(driver) -> None:
    """Measured where it rests: a 40 mm fall reads 40 mm; the first 10 mm of it are
    forgiven in the verdict only (``judged_m``)."""
    _carry_to(driver, TABLE_SPOT)
    high = TABLE_SPOT + (0, 0, 0.045)  # released 40 mm above the table
    driver.move_tcp(high, 1.0, "descend")
    _release(driver)
    driver.move_tcp(high + (0, 0, 0.1), 0.8, "retreat")
    found = driver.backend.inspect_place(demo.tcp_down_at(high))
    assert found.offset_m == pytest.approx(0.040, abs=0.003)
    assert found.judged_m == pytest.approx(0.040 - PLACE_DROP_M, abs=0.003)
    assert found.resting_on == "fixture" and found.speed_mps < 0.01


def test_no_part_released_means_nothing_to_inspect(backend) -> None:
    assert backend.inspect_place(demo.tcp_down_at(TABLE_SPOT)) is None


def test_a_carried_part_pushed_into_the_table_is_a_protective_stop(driver) -> None:
    b = driver.backend
    _carry_to(driver, TABLE_SPOT)
    with pytest.raises(BackendError, match="safety state is protective_stop"):
        driver.move_tcp(TABLE_SPOT - (0, 0, 0.025), 1.5, "push")  # the cube 30 mm into the table
    assert b.read_state().safety is Safety.PROTECTIVE_STOP
    assert (
        "part:cube" in b.world.last_contact.geoms
    )  # pressed onto the table, or forced against a finger


def test_setting_a_part_down_with_a_light_press_is_no_contact(driver) -> None:
    b = driver.backend
    _carry_to(driver, TABLE_SPOT)
    driver.move_tcp(TABLE_SPOT + (0, 0, 0.004), 1.0, "descend")  # 1 mm below the grasp height
    driver.wait(0.3)
    assert b.read_state().safety is Safety.NORMAL
