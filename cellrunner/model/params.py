"""Task params (SPEC sections 4 and 11): typed, bounded values a PLC or the CLI supplies.

- ``int`` / ``bool``: as before; ``int`` params index patterns.
- ``float`` with an optional ``unit`` (``s``, ``m``, ``m/s``, ``deg``, ``N``, or any spelling
  :mod:`.units` knows): bounds and default are read in that unit and stored canonical (m,
  s, N, deg, m/s); the param's name may stand wherever a quantity of that kind is read
  (``wait: dwell``, ``approach: clearance``), see :func:`substitute`.
- ``pose``: a part's pose from a camera or MES, ``{xyz: [m], rpy: [deg]}`` in the frame
  that uses it (``at: {frame: infeed, offset: PARAM}``) or, with ``camera: NAME``, in that
  camera's frame (the target is then ``T_world_camera @ value``), bounded by a box
  ``min: [x, y, z, rx, ry, rz]``, ``max: [...]``; ``check`` verifies the box's corners
  and centre (:meth:`Param.box_values`), its default is the box's centre.
- ``frame``: one of the frames in ``choices`` (the left or the right pallet), named
  wherever a frame is read (``place: {at: side}``); over Modbus the choice's index (0,
  1, ...), over OPC UA and the CLI its name; ``check`` proves every choice. Its default is
  the first choice unless written.
"""

from __future__ import annotations

import itertools
import json
import math
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Strict
from cellrunner.model.units import UNITS, digits, parse_quantity

#: unit spelling -> quantity kind, for float params
UNIT_KINDS: dict[str, str] = {
    u: kind for kind in ("time", "length", "speed", "angle", "force") for u in UNITS[kind][1]
}
POSE_AXES = ("x", "y", "z", "rx", "ry", "rz")

PoseValue = dict[str, list[float]]  # {"xyz": [m, m, m], "rpy": [deg, deg, deg]}
#: a param's value as jobs use it (a frame param's: the frame's name)
ParamValue = int | float | bool | str | PoseValue


class Param(Strict):
    type: Literal["int", "float", "bool", "pose", "frame"] = "int"
    """int, float, bool, pose (x y z in m, rx ry rz in deg, in the frame that uses it) or frame (one of `choices`). Example: `int`"""
    unit: str | None = None
    """Float params: the unit of min, max, default and PLC values. Example: `ms`"""
    min: Any = None
    """Least value accepted (a pose: six values). Example: `0`"""
    max: Any = None
    """Greatest value accepted (a pose: six values). Example: `11`"""
    default: Any = None
    """Value when the PLC or CLI gives none (a pose: the box's centre). Example: `0`"""
    description: str | None = None
    """What the param means, for people. Example: `pallet slot, row by row`"""
    choices: list[str] | None = None
    """Frame params: the frames it may name, in Modbus index order (0, 1, ...). Example: `[pallet_left, pallet_right]`"""
    camera: str | None = None
    """Pose params: the value is the part's pose in this camera's frame (as the vision system reports it, min and max too); it becomes the pose in the world through the camera's calibrated pose. Example: `overhead`"""

    @model_validator(mode="before")
    @classmethod
    def _read_units(cls, data: Any) -> Any:
        """Bounds and default of a float param with a unit, read in that unit."""
        if not isinstance(data, dict):
            return data
        unit, kind = data.get("unit"), data.get("type", "int")
        if unit is None:
            return data
        if kind != "float":
            raise PydanticCustomError("param", f"only float params take a unit, not {kind} params")
        if unit not in UNIT_KINDS:
            raise PydanticCustomError(
                "param", f"unknown unit {unit!r}; known: {', '.join(UNIT_KINDS)}"
            )
        out = dict(data)
        for key in ("min", "max", "default"):
            v = out.get(key)
            if v is not None and not isinstance(v, bool):
                text = v if isinstance(v, str) else f"{v} {unit}"
                out[key] = parse_quantity(text, UNIT_KINDS[unit])
        return out

    @model_validator(mode="after")
    def _consistent(self) -> Param:
        if self.camera is not None and self.type != "pose":
            raise PydanticCustomError(
                "param", f"only pose params take a camera, not {self.type} params"
            )
        if self.type == "pose":
            return self._pose_box()
        if self.type == "frame" or self.choices is not None:
            return self._frame_choices()
        for key in ("min", "max", "default"):
            v = getattr(self, key)
            if v is None:
                continue
            if self.type == "bool" and key == "default":
                if not isinstance(v, bool):
                    raise PydanticCustomError("param", f"default {v!r} is not true or false")
            elif isinstance(v, bool) or not isinstance(v, (int, float)):
                raise PydanticCustomError("param", f"{key} {v!r} is not a number")
            elif self.type == "int" and float(v) != int(v):
                raise PydanticCustomError("param", f"{key} {v!r} is not an int")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise PydanticCustomError("param", f"min {self.min:g} is above max {self.max:g}")
        d = self.default
        below = self.min is not None and d is not None and d < self.min
        above = self.max is not None and d is not None and d > self.max
        if self.type != "bool" and not isinstance(d, bool) and (below or above):
            raise PydanticCustomError(
                "param",
                f"default {d:g} is outside [{self.min:g}, {self.max:g}]"
                if self.min is not None and self.max is not None
                else f"default {d:g} is outside its bounds",
            )
        return self

    def _frame_choices(self) -> Param:
        if self.type != "frame":
            raise PydanticCustomError(
                "param", f"only frame params take choices, not {self.type} params"
            )
        choices = self.choices or []
        if not choices:
            raise PydanticCustomError(
                "param", "a frame param needs choices: the frames it may name, e.g. [left, right]"
            )
        if len(set(choices)) != len(choices):
            raise PydanticCustomError("param", f"choices name a frame twice: {choices}")
        if self.min is not None or self.max is not None or self.unit is not None:
            raise PydanticCustomError("param", "a frame param takes choices, not min, max or unit")
        if self.default is None:
            object.__setattr__(self, "default", choices[0])
        elif self.default not in choices:
            raise PydanticCustomError(
                "param", f"default {self.default!r} is not one of the choices: {', '.join(choices)}"
            )
        return self

    def _pose_box(self) -> Param:
        if self.min is None or self.max is None:
            raise PydanticCustomError(
                "param", "a pose param needs min and max: [x, y, z, rx, ry, rz] in m and deg"
            )
        lo, hi = (_six(self.min, "min"), _six(self.max, "max"))
        for axis, a, b in zip(POSE_AXES, lo, hi, strict=True):
            if a > b:
                raise PydanticCustomError("param", f"min {axis} {a:g} is above max {axis} {b:g}")
        object.__setattr__(self, "min", lo)
        object.__setattr__(self, "max", hi)
        default = self.default
        if default is None:
            default = pose_value([(a + b) / 2 for a, b in zip(lo, hi, strict=True)])
        object.__setattr__(self, "default", self._pose("default", default))
        return self

    @property
    def kind(self) -> str | None:
        """The quantity kind of a float param with a unit (``time``, ``length``, ...)."""
        return UNIT_KINDS.get(self.unit) if self.unit else None

    def coerce(self, name: str, value: Any) -> ParamValue:
        """``value`` as this param's type, or ValueError naming the bounds. A param's
        ``unit`` applies to its min, max and default in the task file and to its Modbus
        register; values given here are SI numbers (s, m, N, deg) or strings with a unit."""
        if self.type == "pose":
            try:
                return self._pose(name, value)
            except PydanticCustomError as exc:
                raise ValueError(exc.message()) from None
        if self.type == "frame":
            return self._choice(name, value)
        if self.type == "bool":
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "false", "1", "0"):
                return value.lower() in ("true", "1")
            if isinstance(value, (int, float)) and value in (0, 1):
                return bool(value)
            raise ValueError(f"param {name!r} must be true or false, got {value!r}")
        x = None
        if isinstance(value, str) and _plain_number(value):  # -p dwell=0.3: an SI number
            value = float(value)
        if isinstance(value, str) and self.kind is not None:
            try:
                x = parse_quantity(value, self.kind)
            except PydanticCustomError as exc:
                raise ValueError(f"param {name!r}: {exc.message()}") from None
        elif not isinstance(value, bool):
            try:
                x = float(value)
            except (TypeError, ValueError):
                x = None
            except OverflowError:  # 10**400
                raise ValueError(
                    f"param {name!r} must be a finite number, got one of {digits(value)} digits"
                ) from None
        if x is not None and not math.isfinite(x):
            raise ValueError(f"param {name!r} must be a finite number, got {value!r}")
        if x is None or (self.type == "int" and x != int(x)):
            raise ValueError(
                f"param {name!r} must be {'an int' if self.type == 'int' else 'a number'}, got {value!r}"
            )
        out: int | float = int(x) if self.type == "int" else x
        if (self.min is not None and out < self.min) or (self.max is not None and out > self.max):
            lo = "-inf" if self.min is None else f"{self.min:g}"
            hi = "inf" if self.max is None else f"{self.max:g}"
            unit = f" {UNITS[self.kind][0]}" if self.kind else ""
            raise ValueError(f"param {name!r} = {out:g}{unit} is outside [{lo}, {hi}]{unit}")
        return out

    def _choice(self, name: str, value: Any) -> str:
        """A frame param's value: a choice's name, or its index (as Modbus sends it)."""
        choices = self.choices or []
        if isinstance(value, str) and value in choices:
            return value
        index = value if isinstance(value, int) and not isinstance(value, bool) else None
        if isinstance(value, str) and value.strip().isdigit():
            index = int(value)
        if index is not None and 0 <= index < len(choices):
            return choices[index]
        raise ValueError(
            f"param {name!r} must be one of {', '.join(choices)} "
            f"(or its index 0-{len(choices) - 1}), got {value!r}"
        )

    def _pose(self, name: str, value: Any) -> PoseValue:
        """A pose value ``{"xyz": [m], "rpy": [deg]}`` (or its JSON text, or six numbers)
        inside this param's box."""
        if isinstance(value, str):
            try:
                value = json.loads(value)
            except ValueError:
                raise PydanticCustomError(
                    "param",
                    f'param {name!r} must be a pose {{"xyz": [x, y, z], "rpy": [rx, ry, rz]}} '
                    f"(m, deg), got {value!r}",
                ) from None
        if isinstance(value, (list, tuple)):
            six = _six(value, name)
        elif isinstance(value, dict) and set(value) <= {"xyz", "rpy"}:
            six = _six([*value.get("xyz", [0, 0, 0]), *value.get("rpy", [0, 0, 0])], name)
        else:
            raise PydanticCustomError(
                "param",
                f'param {name!r} must be a pose {{"xyz": [x, y, z], "rpy": [rx, ry, rz]}} '
                f"(m, deg), got {value!r}",
            )
        for axis, v, a, b in zip(POSE_AXES, six, self.min, self.max, strict=True):
            if not a - 1e-9 <= v <= b + 1e-9:
                unit = "deg" if axis.startswith("r") else "m"
                raise PydanticCustomError(
                    "param",
                    f"param {name!r} {axis} = {v:g} {unit} is outside [{a:g}, {b:g}] {unit}",
                )
        return pose_value(six)

    def box_values(self) -> list[PoseValue]:
        """The centre and every corner of a pose param's box (axes that do not vary are
        not multiplied out): what ``check`` verifies."""
        return box_values(self.min, self.max)


def box_values(low: list[float], high: list[float]) -> list[PoseValue]:
    """The centre and every corner of the pose box ``low``..``high`` (six values each, m
    and deg; axes that do not vary are not multiplied out)."""
    axes = [(a, b) if b > a else (a,) for a, b in zip(low, high, strict=True)]
    centre = pose_value([(a + b) / 2 for a, b in zip(low, high, strict=True)])
    return [centre, *(pose_value(list(c)) for c in itertools.product(*axes))]


def _six(value: Any, what: str) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != 6:
        raise PydanticCustomError(
            "param", f"{what} must be 6 numbers [x, y, z, rx, ry, rz] (m, deg), got {value!r}"
        )
    out = []
    for axis, v in zip(POSE_AXES, value, strict=True):
        kind = "angle" if axis.startswith("r") else "length"
        out.append(parse_quantity(v, kind))
    return out


def pose_value(six: list[float]) -> PoseValue:
    return {"xyz": [float(v) for v in six[:3]], "rpy": [float(v) for v in six[3:]]}


ParamTable = Annotated[dict[str, Param], Field(default_factory=dict)]


def substitute(raw: Any, params: dict[str, Param], values: dict[str, Any]) -> tuple[Any, set[str]]:
    """``raw`` step arguments with every string that names a float param replaced by its
    value, written with its unit (``"2.5 s"``) so that the field reading it checks the
    kind; returns the new arguments and the names used."""
    used: set[str] = set()

    def walk(v: Any) -> Any:
        if isinstance(v, str) and v in params and params[v].type == "frame":
            used.add(v)
            return values.get(v, params[v].default)
        if isinstance(v, str) and v in params and params[v].type == "float":
            used.add(v)
            p = params[v]
            x = values.get(v, p.default)
            return f"{x!r} {UNITS[p.kind][0]}" if p.kind else x
        if isinstance(v, dict):
            return {k: walk(x) for k, x in v.items()}
        if isinstance(v, list):
            return [walk(x) for x in v]
        return v

    return walk(raw), used


def _plain_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
