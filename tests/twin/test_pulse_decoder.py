"""The virtual controller's pulse decoders (twin/pulse_decoder.py) and the UR backend's
reading of their count (backends/ur_conveyor.py): quadrature follows the belt both ways,
edge counting only grows, the int32 count wraps and the backend unwraps it."""

from __future__ import annotations

import pytest

from cellrunner.backends.ur_conveyor import UREncoders, setup_program
from cellrunner.model.conveyor import UR_TICK_REGISTER
from cellrunner.twin.pulse_decoder import PulseDecoders, wrap_int32
from cellrunner.twin.script_text import parse_call


class _Belt:
    """A physics whose encoder on decoder 0 has given ``ticks`` so far."""

    def __init__(self) -> None:
        self.ticks = 0

    def encoder_ticks(self, index: int) -> int | None:
        return self.ticks if index == 0 else None


def _run(decoder_type: int, ticks: list[int]) -> list[int]:
    belt, decoders, registers = _Belt(), PulseDecoders(), [0] * 48
    decoders.enable(0, decoder_type, 8, 9)
    out = []
    for n in ticks:
        belt.ticks = n
        decoders.update(belt, registers)
        out.append(registers[UR_TICK_REGISTER])
    return out


def test_a_quadrature_decoder_follows_the_belt_both_ways_from_its_enable():
    assert _run(1, [100, 130, 180, 150]) == [0, 30, 80, 50]


@pytest.mark.parametrize("decoder_type", [2, 3, 4])
def test_an_edge_counting_decoder_only_counts_up(decoder_type):
    assert _run(decoder_type, [0, 40, 10]) == [0, 40, 70]


def test_a_disabled_decoder_keeps_its_count():
    belt, decoders, registers = _Belt(), PulseDecoders(), [0] * 48
    decoders.enable(0, 1, 8, 9)
    decoders.update(belt, registers)
    belt.ticks = 25
    decoders.update(belt, registers)
    decoders.enable(0, 0, 8, 9)
    belt.ticks = 90
    decoders.update(belt, registers)
    assert decoders.tick_count(0) == 25


def test_the_count_wraps_as_a_signed_int32_and_set_tick_count_sets_it():
    assert wrap_int32(2**31) == -(2**31)
    assert wrap_int32(-(2**31) - 1) == 2**31 - 1
    belt, decoders, registers = _Belt(), PulseDecoders(), [0] * 48
    decoders.enable(0, 1, 0, 1)
    decoders.set_tick_count(0, 2**31 - 2)
    decoders.update(belt, registers)
    belt.ticks = 5
    decoders.update(belt, registers)
    assert registers[UR_TICK_REGISTER] == -(2**31) + 3


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((2, 1, 8, 9), "encoder_index 2 is not 0 or 1"),
        ((0, 5, 8, 9), "decoder_type 5 is not one of 0, 1, 2, 3, 4"),
        ((0, 1, 4, 9), "encoder input A=4 is not one of 0-3 (DI0-3) or 8-11 (CI0-3)"),
    ],
)
def test_a_bad_decoder_setup_is_refused_naming_the_choices(args, message):
    with pytest.raises(ValueError) as err:
        PulseDecoders().enable(*args)
    assert str(err.value) == message


def test_the_backend_setup_program_enables_each_wired_decoder_in_a_sec_program():
    text = setup_program([1, 0])
    lines = text.splitlines()
    assert lines[0] == "sec cellrunner_encoders():" and lines[-1] == "end"
    assert [parse_call(ln) for ln in lines[1:-1]] == [
        ("encoder_enable_pulse_decode", [0, 1, 8, 9], {}),
        ("encoder_enable_pulse_decode", [1, 1, 10, 11], {}),
    ]


class _Stream:
    """The latest RTDE package's output int registers."""

    def __init__(self) -> None:
        self.raw = 0

    def value(self, name: str) -> int:
        assert name == f"output_int_register_{UR_TICK_REGISTER}"
        return self.raw


def test_the_backend_unwraps_the_int32_count_into_travel():
    from cellrunner.model.load import load_cell

    cell = load_cell("cells/conveyor_pick_ur10e.yaml").cell
    encoders = UREncoders(dict(cell.conveyors))
    assert encoders.receive_variables() == [f"output_int_register_{UR_TICK_REGISTER}"]
    assert encoders.travel_m("belt", _Stream(), 0.0) is None  # not configured yet
    encoders.restart_counts()
    stream = _Stream()
    travel = []
    for raw in (2**31 - 4000, 2**31 - 1, -(2**31) + 3999):
        stream.raw = raw
        travel.append(encoders.travel_m("belt", stream, 0.0))
    assert travel == pytest.approx([0.0, 3999 / 4000, 2.0 - 1 / 4000])
    assert encoders.travel_m("nothing", stream, 0.0) is None
