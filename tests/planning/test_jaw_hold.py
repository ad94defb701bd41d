"""check holds a jaw grip to the twin's rule (issue 33): across the jaw axis the part is
held by the pads' friction alone (2 x mu x the clamp force), against the part's weight
and the accelerations of the moves that carry it; a part that would slide more than
JAW_SLIP_M in the jaws is refused with the acceleration that would hold it."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.model.jaw_grip import (
    JAW_GRIP_FORCE_N,
    JAW_PAD_FRICTION,
    grip_friction,
    jaws_hold_N,
    slip_load_N,
    slip_m,
)
from cellrunner.sim.description import GripperDescription
from tests.conftest import DEMO_CELL, ROOT
from tests.rig import json_of

X = np.array([1.0, 0.0, 0.0])  # the jaw axis of a TCP whose X is the world's


def test_the_pads_hold_across_their_axis_and_clamp_along_it():
    weight = np.array([0.0, 0.0, 3.0 * 9.81])
    assert slip_load_N(weight, X) == pytest.approx(3.0 * 9.81)
    along = np.array([50.0, 0.0, 0.0])  # pushed into a pad: no friction needed
    assert slip_load_N(along, X) == pytest.approx(0.0)
    assert jaws_hold_N(0.5) == pytest.approx(2 * JAW_PAD_FRICTION * JAW_GRIP_FORCE_N)
    assert grip_friction(1.5) == 1.5  # the larger coefficient, as the twin combines them


def test_a_jolt_slides_a_fraction_of_a_millimetre_a_sustained_excess_millimetres():
    period, holds, mass = 0.002, 80.0, 5.0
    jolt = np.r_[np.full(50, 60.0), np.full(3, 100.0), np.full(50, 60.0)]
    assert slip_m(jolt, holds, mass, period)[-1] < 0.2e-3  # 0.14 mm
    sustained = np.r_[np.full(50, 60.0), np.full(100, 100.0)]
    assert slip_m(sustained, holds, mass, period)[-1] > 0.005


def test_the_twin_builds_its_pads_with_the_rule_s_numbers():
    g = GripperDescription()
    assert (g.grip_force_N, g.friction) == (JAW_GRIP_FORCE_N, JAW_PAD_FRICTION)


def _heavy_demo(tmp_path, mass_kg: float):
    cell = tmp_path / "cell.yaml"
    cell.write_text(
        DEMO_CELL.read_text().replace("mass: 0.3, at: infeed", f"mass: {mass_kg}, at: infeed")
    )
    for mesh in DEMO_CELL.parent.iterdir():
        if mesh.suffix.lower() == ".stl":
            (tmp_path / mesh.name).write_bytes(mesh.read_bytes())
    task = tmp_path / "task.yaml"
    task.write_text(
        (ROOT / "tasks/pick_place.yaml").read_text().replace(", force: {min: 2, max: 40}", "")
    )
    return cell, task


def test_a_block_heavier_than_the_pads_hold_is_refused_at_its_grip(tmp_path):
    """9 kg between pads that hold 80 N: the twin loses it in transit (2)."""
    cell, task = _heavy_demo(tmp_path, 9.0)
    out = json_of("check", str(cell), str(task), "--no-cache")
    assert not out["ok"]
    assert out["errors"][0].startswith(
        "step 4 grip 'infeed': the jaws hold 80 N by friction across their axis but part "
        "'block' weighs 88.3 N (9 kg): it slides out of the jaws"
    ), out["errors"]


def test_a_carry_that_beats_the_pads_friction_names_the_acceleration_that_holds(tmp_path):
    """7.5 kg (73.6 N, under the 80 N): the lift's acceleration slides it (the twin
    loses it in transit, 2); the fix names the acceleration that holds it."""
    cell, task = _heavy_demo(tmp_path, 7.5)
    out = json_of("check", str(cell), str(task), "--no-cache")
    assert not out["ok"]
    first = out["errors"][0]
    assert first.startswith("step 5 lift 'infeed': carrying part 'block' (7.5 kg)"), first
    assert "the part slides in the jaws" in first
    assert "keep the part's acceleration under 0.9 m/s^2" in first


def test_the_demo_s_light_block_holds(tmp_path):
    cell, task = _heavy_demo(tmp_path, 0.3)
    out = json_of("check", str(cell), str(task), "-p", "slot=0", "--no-cache")
    assert out["ok"], out["errors"]
