"""Sanity warnings: values that are valid but look like a slip, with a "did you mean".

Bare numbers are metres (SPEC section 2), so a length written in millimetres without its
unit (``approach: 150``) is read as 150 m and only fails much later, as "out of reach"
on every slot. These checks run at load time (so ``validate`` shows them) and warn with
the value read as millimetres:

    tasks/t.yaml:5:17: warning: steps[1].pick.approach: 150 m is longer than the UR5e's
    reach (0.85 m); did you mean 150 mm = 0.15 m? (write '150 mm')

They also warn about a frame far beyond the arm's reach (a cell drawn in other world
coordinates than the robot's mount: a cell in the wrong place) and a fixture with no
pose (it would stand at the world origin, in the robot's base).
Only bare numbers are judged: a value written with a unit says what it means.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from cellrunner.model.rotation import rpy_rows
from cellrunner.model.source import PathKey

if TYPE_CHECKING:
    from cellrunner.model.loaded import LoadedCell, LoadedTask
    from cellrunner.model.robots import RobotSpec


class Warner(Protocol):
    """Where the warnings go: ``Report`` or a prefixed view of it."""

    def warn(self, path: PathKey, message: str) -> None: ...


#: keys of task step arguments that hold a length (m)
STEP_LENGTH_KEYS = ("approach", "lift", "retreat", "distance", "depth", "max_distance")
#: keys of task step arguments that hold a TCP speed (m/s)
STEP_SPEED_KEYS = ("speed",)
#: a mount, fixture position or size beyond this (m) is not a robot cell
CELL_EXTENT_M = 20.0
#: a tool offset beyond this (m) is not a tool
TOOL_EXTENT_M = 1.5


def _number(value: Any) -> float | None:
    """A bare number (not a bool, not a string with a unit), else None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def _get(raw: Any, path: PathKey) -> Any:
    for part in path:
        try:
            raw = raw[part]
        except (KeyError, IndexError, TypeError):
            return None
    return raw


def _mm(value: float) -> str:
    return f"did you mean {value:g} mm = {value / 1000:g} m? (write '{value:g} mm')"


def _vector_mm(values: list[float]) -> str:
    metres = ", ".join(f"{v / 1000:g}" for v in values)
    example = next((v for v in values if v), values[0])
    return f"did you mean mm, i.e. [{metres}] m? (write each as e.g. '{example:g} mm')"


def check_cell(loaded: LoadedCell, report: Warner) -> None:
    """Warn about a loaded cell's lengths that look like mm, a frame far beyond reach,
    and fixtures without a pose; ``report.warn(path, message)`` receives them."""
    raw = loaded.source.data
    cell = loaded.cell
    spec = loaded.spec
    model = spec.label
    _vector(raw, ("robot", "mount", "xyz"), CELL_EXTENT_M, report, "the robot's mount")
    _vector(raw, ("tool", "tcp", "xyz"), TOOL_EXTENT_M, report, "a tool centre point offset")
    for i, _ in enumerate(cell.tool.geometry):
        _shape(raw, ("tool", "geometry", i), TOOL_EXTENT_M, report)
    for i, fixture in enumerate(cell.fixtures):
        base = ("fixtures", i)
        if fixture.pose is None and fixture.xyz is None:
            report.warn(
                base,
                f"fixture {fixture.name!r} has no pose: it stands at the world origin, "
                "where the robot is usually mounted; give it 'pose: {xyz: [x, y, z]}' (m)",
            )
        _shape(raw, base, CELL_EXTENT_M, report)
    for i, _ in enumerate(cell.parts):
        _shape(raw, ("parts", i), TOOL_EXTENT_M, report)
    mount = cell.robot.mount
    shoulder = [  # the mount's z axis times the shoulder height, from the mount
        t + row[2] * spec.d_m[0] for t, row in zip(mount.xyz, rpy_rows(mount.rpy), strict=True)
    ]
    slips, far = {}, {}
    for name, frame in cell.frames.items():
        if frame.parent != "world":
            _vector(raw, ("frames", name, "xyz"), 3 * spec.reach_m, report, "a frame offset")
            continue
        distance_m = math.dist(frame.xyz, shoulder)
        values = _get(raw, ("frames", name, "xyz"))
        bare = isinstance(values, list) and all(_number(v) is not None for v in values)
        if (
            bare
            and distance_m > 10 * spec.reach_m
            and _mm_within(frame.xyz, shoulder, 2 * spec.reach_m)
        ):
            slips[name] = distance_m
        elif distance_m > 2 * spec.reach_m:
            far[name] = distance_m
    reach = f"(reach {spec.reach_m:.2f} m)"
    for name, distance_m in slips.items():
        report.warn(
            ("frames", name, "xyz"),
            f"frame {name!r} is {distance_m:.2f} m from the {model}'s shoulder "
            f"{reach}; {_vector_mm([float(v) for v in cell.frames[name].xyz])}",
        )
    if far:
        centre = [
            sum(c) / len(far) for c in zip(*(cell.frames[name].xyz for name in far), strict=True)
        ]
        for name, distance_m in far.items():
            report.warn(
                ("frames", name, "xyz"),
                f"frame {name!r} is {distance_m:.2f} m from the {model}'s "
                f"shoulder {reach}: is the cell in the wrong place, or the robot? robot.mount is at "
                f"{_fmt_xyz(mount.xyz)}; did you mean a mount near {_fmt_xyz([centre[0], centre[1], mount.xyz[2]])}, "
                "among the frames?",
            )


def _mm_within(xyz: Iterable[float], shoulder: Sequence[float], limit_m: float) -> bool:
    return math.dist([float(v) / 1000 for v in xyz], shoulder) <= limit_m


def _fmt_xyz(xyz: Iterable[float]) -> str:
    return "[" + ", ".join(f"{float(v):.4g}" for v in xyz) + "]"


def _vector(raw: Any, path: PathKey, limit_m: float, report: Warner, what: str) -> None:
    values = _get(raw, path)
    if not isinstance(values, list):
        return
    maybe = [_number(v) for v in values]
    numbers = [n for n in maybe if n is not None]
    if len(numbers) < len(maybe):
        return
    if max(abs(n) for n in numbers) > limit_m:
        report.warn(
            path,
            f"{_fmt_xyz(numbers)} m is too large for {what} (over {limit_m:g} m); "
            f"{_vector_mm(numbers)}",
        )


def _shape(raw: Any, base: PathKey, limit_m: float, report: Warner) -> None:
    """Sizes of a box, cylinder or sphere and a placed shape's xyz, written inline or as pose."""
    for key, sizes in (
        ("box", ("size",)),
        ("cylinder", ("radius", "length")),
        ("sphere", ("radius",)),
    ):
        for size in sizes:
            path = (*base, key, size)
            value = _get(raw, path)
            if isinstance(value, list):
                _vector(raw, path, limit_m, report, f"a {key}'s size")
            elif (n := _number(value)) is not None and n > (
                limit := limit_m / 4 if size == "radius" else limit_m
            ):
                report.warn(
                    path,
                    f"{n:g} m is larger than any {key} {size} in a cell (over {limit:g} m); {_mm(n)}",
                )
    for path in ((*base, "xyz"), (*base, "pose", "xyz")):
        _vector(raw, path, limit_m, report, "a shape's position")


def check_task(loaded_task: LoadedTask, cell: LoadedCell, report: Warner) -> None:
    """Warn about a task's step lengths and speeds that look like mm (and mm/s)."""
    from cellrunner.model.robots import robot_spec

    spec = robot_spec(cell.cell.robot.model)
    model = spec.label
    steps = _get(loaded_task.source.data, ("steps",))
    if isinstance(steps, list):
        _walk(steps, ("steps",), spec, model, report)


def _walk(node: Any, path: PathKey, spec: RobotSpec, model: str, report: Warner) -> None:
    if isinstance(node, dict):
        for key, value in node.items():
            here = (*path, key)
            n = _number(value)
            if key in STEP_LENGTH_KEYS and n is not None and n > spec.reach_m:
                report.warn(
                    here,
                    f"{n:g} m is longer than the {model}'s reach ({spec.reach_m:.2f} m); {_mm(n)}",
                )
            elif key in STEP_SPEED_KEYS and n is not None and n > spec.tcp_speed_max_mps:
                report.warn(
                    here,
                    f"{n:g} m/s is above the {model}'s {spec.tcp_speed_max_mps:g} m/s; did you mean "
                    f"{n:g} mm/s = {n / 1000:g} m/s? (write '{n:g} mm/s')",
                )
            elif key == "pitch" and isinstance(value, list):
                maybe = [_number(v) for v in value]
                numbers = [x for x in maybe if x is not None]
                if numbers and len(numbers) == len(maybe) and max(numbers) > spec.reach_m:
                    report.warn(
                        here,
                        f"pitch {_fmt_xyz(numbers)} m spans more than the {model}'s reach; "
                        f"{_vector_mm(numbers)}",
                    )
            elif key == "offset" and isinstance(value, dict):
                _vector(value, ("xyz",), spec.reach_m, _Prefixed(report, here), "an offset")
            else:
                _walk(value, here, spec, model, report)
    elif isinstance(node, list):
        for i, item in enumerate(node):
            _walk(item, (*path, i), spec, model, report)


class _Prefixed:
    """A report whose paths are taken under ``prefix`` (for a sub-mapping's checks)."""

    def __init__(self, report: Warner, prefix: PathKey) -> None:
        self.report, self.prefix = report, prefix

    def warn(self, path: PathKey, message: str) -> None:
        self.report.warn((*self.prefix, *path), message)


__all__ = ["check_cell", "check_task"]
