"""Task params in Modbus holding registers (SPEC sections 7 and 11).

The param window is registers 4-19 (16 registers), filled in the task's ``params:``
order: an ``int``, ``bool`` or ``float`` param takes one int16 register (a float with a
``unit`` is counted in that unit: ``unit: ms`` reads 250 as 250 ms); a ``pose`` param
takes six: x, y, z in 0.1 mm and rx, ry, rz in 0.01 deg. Params past the window keep
their defaults.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from cellrunner.model.params import UNIT_KINDS
from cellrunner.model.units import UNITS

PARAM_FIRST = 4
N_PARAM_REGS = 16
POSE_REGS = 6
MM_PER_COUNT = 0.1
DEG_PER_COUNT = 0.01


def to_int16(raw: int) -> int:
    """A register's 16 bits as a signed value (-32768..32767)."""
    return raw - 0x10000 if raw & 0x8000 else raw


def from_int16(value: int) -> int:
    return value & 0xFFFF


def decode_params(
    layout: Sequence[tuple[str, str, str | None]], registers: Sequence[int]
) -> dict[str, Any]:
    """Param values from the window's ``registers`` for ``layout`` = (name, type, unit)
    in the task's order: ints, SI numbers for params with a unit (250 counts of ``ms``:
    0.25 s), pose dicts ``{"xyz": [m], "rpy": [deg]}``. The task's param check judges the
    values."""
    out: dict[str, Any] = {}
    i = 0
    for name, kind, unit in layout:
        width = POSE_REGS if kind == "pose" else 1
        if i + width > len(registers):
            break
        words = [to_int16(r) for r in registers[i : i + width]]
        i += width
        if kind == "pose":
            out[name] = {
                "xyz": [w * MM_PER_COUNT / 1000.0 for w in words[:3]],
                "rpy": [w * DEG_PER_COUNT for w in words[3:]],
            }
        elif unit:
            kind = UNIT_KINDS[unit]
            out[name] = words[0] * UNITS[kind][1][unit]
        else:
            out[name] = words[0]
    return out


def encode_pose(xyz_m: Sequence[float], rpy_deg: Sequence[float]) -> list[int]:
    """Six register words (uint16 as written on the wire) for a pose param."""
    counts = [round(v * 1000.0 / MM_PER_COUNT) for v in xyz_m] + [
        round(v / DEG_PER_COUNT) for v in rpy_deg
    ]
    for c in counts:
        if not -0x8000 <= c <= 0x7FFF:
            # ValueError, as struct's own for a number a register cannot hold (a client's helper)
            raise ValueError(f"pose value {c} counts does not fit an int16 register")
    return [from_int16(c) for c in counts]
