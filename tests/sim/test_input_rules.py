"""The cell's sim: input rules, on simulated time (SPEC section 11)."""

from __future__ import annotations

import pytest

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.sim import demo
from cellrunner.sim.input_rules import InputRuleDescription, InputRules


def _run(rules: InputRules, outputs_at, until_s: float, rate_hz: float = 500.0):
    """Evaluate ``rules`` every period; ``outputs_at(t)`` gives the outputs; returns the
    (t, inputs) samples."""
    out = []
    for k in range(int(until_s * rate_hz) + 1):
        t = k / rate_hz
        out.append((t, rules.evaluate(t, outputs_at(t), [])))
    return out


def _edges(samples, channel):
    edges, last = [], False
    for t, inputs in samples:
        if inputs[channel] != last:
            edges.append((round(t, 3), inputs[channel]))
            last = inputs[channel]
    return edges


def test_follows_copies_the_output_after_its_delay() -> None:
    rules = InputRules((InputRuleDescription("DI2", "follows", output="DO1", delay_s=1.5),))
    samples = _run(rules, lambda t: {"DO1": 1.0 <= t < 4.0}, 7.0)
    assert _edges(samples, "DI2") == [(2.5, True), (5.5, False)]


def test_pulse_after_rises_once_per_rise_of_the_output() -> None:
    rules = InputRules(
        (InputRuleDescription("DI3", "pulse_after", output="DO2", delay_s=2.0, width_s=0.5),)
    )
    samples = _run(rules, lambda t: {"DO2": 0.5 <= t < 0.7 or t >= 5.0}, 9.0)
    assert _edges(samples, "DI3") == [(2.5, True), (3.0, False), (7.0, True), (7.5, False)]


def test_part_at_sees_a_part_within_its_radius() -> None:
    rules = InputRules(
        (InputRuleDescription("DI1", "part_at", point_world_m=(0.4, 0.0, 0.9), within_m=0.02),)
    )
    assert rules.evaluate(0.0, {}, [(0.41, 0.01, 0.9)]) == {"DI1": True}
    assert rules.evaluate(0.0, {}, [(0.43, 0.0, 0.9)]) == {"DI1": False}
    assert rules.evaluate(0.0, {}, []) == {"DI1": False}


def test_the_twin_drives_ruled_inputs_and_refuses_to_script_them() -> None:
    rules = (
        InputRuleDescription("DI3", "part_at", point_world_m=demo.CUBE_XYZ_M),
        InputRuleDescription("DI2", "follows", output="DO0", delay_s=0.1),
    )
    backend = SimBackend(
        demo.demo_description(input_rules=rules, io_inputs=("DI0", "DI1", "DI2", "DI3"))
    )
    backend.connect()
    try:
        assert backend.read_state().inputs["DI3"] is True  # the cube lies at its spot
        backend.set_output("DO0", True)
        for _ in range(40):  # 80 ms
            backend.wait_period()
        assert backend.read_state().inputs["DI2"] is False
        for _ in range(15):
            backend.wait_period()
        assert backend.read_state().inputs["DI2"] is True
        with pytest.raises(Exception, match="driven by a twin sensor"):
            backend.set_input("DI2", False)
    finally:
        backend.close()
