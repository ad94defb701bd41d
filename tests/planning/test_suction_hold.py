"""check holds a vacuum grip to the twin's rule (issue 33): the seal's load (pull along
the cup axis plus shear over friction, low-pass filtered) against the gripper's
holding_force, from the part's weight and the accelerations of the moves that carry it."""

from __future__ import annotations

import numpy as np
import pytest

from bench.agreement import cli
from bench.cellgen import generate
from cellrunner.model.suction import CUP_FRICTION, filtered_N, seal_load_N

DOWN = np.array([0.0, 0.0, -1.0])  # the cup axis of a tool pointing down, into the part


def test_a_hanging_part_pulls_its_weight_and_a_sideways_push_counts_over_friction():
    weight = np.array([0.0, 0.0, 2.0 * 9.81])  # what the cups exert on a 2 kg part at rest
    assert seal_load_N(weight, DOWN) == pytest.approx(2.0 * 9.81)
    sideways = weight + [2.0 * 5.0, 0.0, 0.0]  # and 5 m/s^2 along X
    assert seal_load_N(sideways, DOWN) == pytest.approx(2.0 * 9.81 + 10.0 / CUP_FRICTION)
    pushed = np.array([0.0, 0.0, -30.0])  # pressed into the cups: no pull
    assert seal_load_N(pushed, DOWN) == pytest.approx(0.0)


def test_the_seal_filters_a_jolt_but_not_a_sustained_pull():
    period = 0.002
    jolt = np.r_[np.full(50, 20.0), np.full(3, 200.0), np.full(50, 20.0)]
    assert filtered_N(jolt, period).max() < 45.0
    sustained = np.r_[np.full(50, 20.0), np.full(200, 200.0)]
    assert filtered_N(sustained, period).max() > 190.0


def _check(tmp_path, case, holding_N=None):
    if holding_N is not None:
        case.cell["tool"]["gripper"]["holding_force"] = holding_N
    cell, task = case.write(tmp_path)
    return cli("check", str(cell), str(task), "--no-cache")


def test_cups_sized_for_the_arm_hold_and_weaker_ones_are_refused_at_the_move_that_tears(
    tmp_path,
):
    case = generate(3012, "feasible")  # a UR10e, 1.65 kg on suction cups
    assert case.cell["tool"]["gripper"]["kind"] == "vacuum"
    mass = case.cell["parts"][0]["mass"]
    code, out = _check(tmp_path / "ok", case)
    assert code == 0, out["errors"]
    # over its weight, under what the carrying moves pull: the move that pulls it off
    code, out = _check(tmp_path / "dynamic", case, round(mass * 9.81 * 1.5, 1))
    assert code == 1
    error = out["errors"][0]
    assert "the part tears off" in error and "over the" in error
    assert error.split(":")[0].split()[2] in ("lift", "approach", "retreat", "move", "descend")
    # under its weight: it falls at the grip
    code, out = _check(tmp_path / "weak", case, round(mass * 9.81 * 0.8, 1))
    assert code == 1
    assert out["errors"][0].startswith("step 4 grip 'infeed': the cups hold")
    assert "it falls off the cups" in out["errors"][0]
