import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import TypeAdapter, ValidationError

from cellrunner.model.units import (
    Angle,
    Fraction,
    PositiveLength,
    Speed,
    looks_like_radians,
    parse_quantity,
)


@pytest.mark.parametrize(
    "text,kind,expected",
    [
        ("500 mm", "length", 0.5),
        ("50cm", "length", 0.5),
        ("1.2 rad", "angle", math.degrees(1.2)),
        ("250 mm/s", "speed", 0.25),
        ("90 deg/s", "angular_speed", 90.0),
        ("1 rad/s", "angular_speed", math.degrees(1)),
        ("300 g", "mass", 0.3),
        ("1500 ms", "time", 1.5),
        ("2 kN", "force", 2000.0),
        ("50%", "fraction", 0.5),
        (0.3, "length", 0.3),
        (7, "time", 7.0),
    ],
)
def test_units_parse(text, kind, expected):
    assert parse_quantity(text, kind) == pytest.approx(expected)


def _msg(adapter, value):
    with pytest.raises(ValidationError) as exc:
        adapter.validate_python(value)
    return exc.value.errors()[0]["msg"]


def test_wrong_unit_message_names_value_and_valid_units():
    assert _msg(TypeAdapter(PositiveLength), "5 kg") == (
        "cannot read '5 kg' as a length; write a number with one of the units m, cm, mm, e.g. '500 mm'"
    )


def test_bound_message():
    assert _msg(TypeAdapter(PositiveLength), -1) == "must be > 0 m, got -1 m"
    assert _msg(TypeAdapter(Fraction), 1.5) == "must be <= 1, got 1.5"


def test_booleans_are_not_numbers():
    assert "got True" in _msg(TypeAdapter(Speed), True)


def test_angle_over_360_is_an_error():
    assert (
        _msg(TypeAdapter(Angle), 361)
        == "angle 361 deg is out of range [-360, 360]; angles are in degrees"
    )
    assert TypeAdapter(Angle).validate_python(-360) == -360


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_mm_and_m_agree(x):
    assert parse_quantity(f"{x!r} mm", "length") == pytest.approx(x / 1000, rel=1e-12, abs=1e-15)


def test_radians_heuristic():
    assert looks_like_radians([0, -1.57, 1.57, -1.57, -1.57, 0])
    assert not looks_like_radians([0, -90, 90, -90, -90, 0])
    assert not looks_like_radians([0, 0, 0, 0, 0, 0])
    assert not looks_like_radians([0, 1, 2, 3, 4, 5])  # small whole degrees are plausible
