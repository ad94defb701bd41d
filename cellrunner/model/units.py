"""Quantities with units (SPEC section 2).

Bare numbers are SI (m, s, N, kg, m/s) or degrees for angles and angular speeds. Any
number may instead be a string with an explicit unit: ``"500 mm"``, ``"1.2 rad"``,
``"250 mm/s"``, ``"90 deg/s"``. Parsing returns a float in the canonical unit of its
kind (m, s, N, kg, m/s, m/s^2, deg, deg/s, deg/s^2).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import BeforeValidator, WithJsonSchema
from pydantic_core import PydanticCustomError

_R = 180.0 / math.pi

#: kind -> (canonical unit, {unit spelling: factor to canonical})
UNITS: dict[str, tuple[str, dict[str, float]]] = {
    "length": ("m", {"m": 1.0, "cm": 0.01, "mm": 0.001}),
    "time": ("s", {"s": 1.0, "ms": 0.001, "min": 60.0}),
    "force": ("N", {"N": 1.0, "kN": 1000.0}),
    "mass": ("kg", {"kg": 1.0, "g": 0.001}),
    "speed": ("m/s", {"m/s": 1.0, "mm/s": 0.001, "cm/s": 0.01, "m/min": 1 / 60}),
    "accel": ("m/s^2", {"m/s^2": 1.0, "m/s2": 1.0, "mm/s^2": 0.001, "mm/s2": 0.001}),
    "angle": ("deg", {"deg": 1.0, "°": 1.0, "rad": _R}),
    "angular_speed": ("deg/s", {"deg/s": 1.0, "°/s": 1.0, "rad/s": _R, "rpm": 6.0}),
    "angular_accel": (
        "deg/s^2",
        {"deg/s^2": 1.0, "deg/s2": 1.0, "°/s^2": 1.0, "rad/s^2": _R, "rad/s2": _R},
    ),
    "fraction": ("", {"": 1.0, "%": 0.01}),
}
_ANGLE_KINDS = ("angle", "angular_speed", "angular_accel")
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\d\s].*?)?\s*$")


def _fmt(x: float) -> str:
    return f"{x:g}"


def _fail(message: str) -> PydanticCustomError:
    return PydanticCustomError("quantity", message)


_LARGEST_INT = 2**1023  # the largest int a float holds, roughly (float() overflows beyond)


def digits(value: int) -> int:
    """The decimal digits of ``value``, without printing it (Python refuses to print
    ints of more than 4300 digits)."""
    return int(abs(value).bit_length() * math.log10(2)) + 1


def parse_quantity(value: Any, kind: str) -> float:
    """``value`` (a number, or a string with a unit) in the canonical unit of ``kind``.

    Raises a pydantic error whose message names the value and the accepted units.
    """
    unit0, table = UNITS[kind]
    units = ", ".join(u for u in table if u) or "none"
    noun = kind.replace("_", " ")
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise _fail(
            f"expected a {noun} (a number in {unit0 or 'plain units'}, or a string "
            f"with a unit: {units}), got {value!r}"
        )
    if isinstance(value, str):
        match = _NUMBER_UNIT.match(value)
        unit = (match.group(2) or "").strip() if match else None
        if match is None or unit not in table:
            raise _fail(
                f"cannot read {value!r} as a {noun}; write a number with one of the "
                f"units {units}, e.g. '{_example(kind)}'"
            )
        number = float(match.group(1)) * table[unit]
    elif isinstance(value, int) and abs(value) > _LARGEST_INT:
        raise _fail(f"a number of {digits(value)} digits is not a {noun}")
    else:
        number = float(value)
    if not math.isfinite(number):
        raise _fail(f"{value!r} is not a finite number")
    if kind == "angle" and abs(number) > 360.0 + 1e-9:
        raise _fail(f"angle {_fmt(number)} deg is out of range [-360, 360]; angles are in degrees")
    return number


def _example(kind: str) -> str:
    return {
        "length": "500 mm",
        "time": "1.5 s",
        "force": "20 N",
        "mass": "300 g",
        "speed": "250 mm/s",
        "accel": "1200 mm/s^2",
        "angle": "1.2 rad",
        "angular_speed": "90 deg/s",
        "angular_accel": "300 deg/s^2",
        "fraction": "50%",
    }[kind]


def quantity(
    kind: str,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
) -> Any:  # a type form: Annotated[float, ...]
    """An annotated float type for pydantic: parses units and checks bounds."""
    unit0 = UNITS[kind][0]

    def validate(value: Any) -> float:
        x = parse_quantity(value, kind)
        shown = f"{_fmt(x)} {unit0}".strip()
        checks: tuple[tuple[float | None, Callable[[float], bool], str], ...] = (
            (gt, lambda b: x > b, ">"),
            (ge, lambda b: x >= b, ">="),
            (lt, lambda b: x < b, "<"),
            (le, lambda b: x <= b, "<="),
        )
        for bound, ok, word in checks:
            if bound is not None and not ok(bound):
                raise _fail(f"must be {word} {_fmt(bound)} {unit0}".rstrip() + f", got {shown}")
        return x

    schema: dict[str, Any] = {
        "anyOf": [
            {"type": "number", **_json_bounds(gt, ge, lt, le)},
            {"type": "string", "pattern": _unit_pattern(kind)},
            {
                "type": "string",
                "pattern": r"^[A-Za-z_][A-Za-z0-9_\-]*$",
                "description": "the name of a task param of type float (with a unit of this kind)",
            },
        ],
        "description": f"{kind.replace('_', ' ')} in {unit0 or 'plain units'}, or a string with "
        f"a unit ({', '.join(u for u in UNITS[kind][1] if u)})",
    }
    return Annotated[float, BeforeValidator(validate), WithJsonSchema(schema)]


def _json_bounds(
    gt: float | None, ge: float | None, lt: float | None, le: float | None
) -> dict[str, float]:
    out = {}
    for key, v in (
        ("exclusiveMinimum", gt),
        ("minimum", ge),
        ("exclusiveMaximum", lt),
        ("maximum", le),
    ):
        if v is not None:
            out[key] = v
    return out


def _unit_pattern(kind: str) -> str:
    units = "|".join(re.escape(u) for u in UNITS[kind][1] if u)
    return rf"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*({units})\s*$"


if TYPE_CHECKING:  # to a type checker each quantity is the float it validates to
    Length = float
    PositiveLength = float
    NonNegativeLength = float
    Duration = float
    PositiveDuration = float
    Force = float
    Mass = float
    Speed = float
    Angle = float
    AngularSpeed = float
    AngularAccel = float
    Fraction = float
else:
    Length = quantity("length")
    PositiveLength = quantity("length", gt=0)
    NonNegativeLength = quantity("length", ge=0)
    Duration = quantity("time", ge=0)
    PositiveDuration = quantity("time", gt=0)
    Force = quantity("force", ge=0)
    Mass = quantity("mass", ge=0)
    Speed = quantity("speed", gt=0)
    Angle = quantity("angle")
    AngularSpeed = quantity("angular_speed", gt=0)
    AngularAccel = quantity("angular_accel", gt=0)
    Fraction = quantity("fraction", gt=0, le=1)


def looks_like_radians(values: list[float]) -> bool:
    """True when a list of bare angles reads like radians written by mistake.

    All magnitudes within 2*pi, at least one of them not a whole number and above 0.5:
    a pose in degrees with only such small fractional angles is implausible.
    """
    if not values or any(abs(v) > 2 * math.pi + 1e-9 for v in values):
        return False
    return any(abs(v) > 0.5 and abs(v - round(v)) > 1e-6 for v in values)
