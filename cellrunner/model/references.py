"""Checks of a task's references against its cell: frames, IO names, params, patterns."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from cellrunner.model.checks import check_io_name, check_radians
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.step import StepKind

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.model.loaded import LoadedCell, LoadedTask, StepSpec
    from cellrunner.model.pattern import Pattern
    from cellrunner.model.report import Report
    from cellrunner.model.source import PathKey

_LINEAR_KINDS = ("descend", "linear")


def check_task_references(task: LoadedTask, loaded: LoadedCell, report: Report) -> None:
    cell = loaded.cell
    frames = list(cell.frames)
    needs_gripper = False
    for step in _all_steps([*task.steps, *task.on_error]):
        kind, args, path = step.kind, step.args, step.path
        if getattr(args, "pattern", None) is not None and kind not in ("pick", "place"):
            if kind == "move" and not (isinstance(args.to, str) and args.to != "home"):
                report.error(
                    path + ("pattern",), "a pattern offsets a frame; this move's target is not one"
                )
            else:
                _check_pattern(task, args.pattern, path + ("pattern",), report)
        if kind == "align":
            _check_align(task, cell, step, report)
        elif kind == "move":
            if isinstance(args.to, str) and args.to != "home" and args.to not in cell.frames:
                report.error(path + ("to",), unknown_name("target", args.to, ["home", *frames]))
            if isinstance(args.to, list):
                raw_path = path if _is_short(report, path) else path + ("to",)
                check_radians(report.source.data, raw_path, report)
        elif kind in ("approach", "insert", *_LINEAR_KINDS):
            if args.to not in cell.frames:
                report.error(path + ("to",), unknown_name("frame", args.to, frames))
            fixtures = [f.name for f in cell.fixtures]
            for i, name in enumerate(getattr(args, "contact", None) or ()):
                if name not in fixtures:
                    report.error(path + ("contact", i), unknown_name("fixture", name, fixtures))
        elif kind in ("pick", "place"):
            if args.at not in cell.frames:
                report.error(path + ("at",), unknown_name("frame", args.at, frames))
            if args.pattern is not None:
                _check_pattern(task, args.pattern, path + ("pattern",), report)
            if args.at_offset is not None:
                _check_pose_param(task, cell, args.at_offset, path + ("at", "offset"), report)
            if kind == "place" and args.confirm is not None:
                check_io_name(cell, args.confirm, "inputs", path + ("confirm",), report)
            needs_gripper = True
            grip = args.grip if kind == "pick" else args.release
            if grip.confirm is not None:
                check_io_name(
                    cell,
                    grip.confirm,
                    "inputs",
                    path + ("grip" if kind == "pick" else "release", "confirm"),
                    report,
                )
        elif kind in ("grip", "release"):
            needs_gripper = True
            if args.confirm is not None:
                check_io_name(cell, args.confirm, "inputs", path + ("confirm",), report)
        elif kind == "set_output":
            for name in args.values:
                check_io_name(cell, name, "outputs", path + (name,), report, at_key=True)
        elif kind == "wait_input":
            check_io_name(cell, args.input, "inputs", path + ("input",), report)
        elif kind == "change_tool":
            _check_change_tool(cell, args.tool, path, report)
    _check_tool_at_end(task, cell, report)
    if needs_gripper and cell.tool.gripper is None:
        report.error(
            ("steps",), f"the task grips and releases but cell {cell.cell!r} has no tool.gripper"
        )
    for name, param in task.task.params.items():
        for i, choice in enumerate(param.choices or ()):
            if choice not in cell.frames:
                report.error(("params", name, "choices", i), unknown_name("frame", choice, frames))
        if param.default is None:
            report.error(
                ("params", name),
                f"param {name!r} needs a default (the value used when "
                "the PLC or the CLI gives none)",
                at_key=True,
            )


def _is_short(report: Report, path: PathKey) -> bool:
    """True when the step at ``path`` was written in short form (``move: [..]``)."""
    value = report.source.data
    for part in path:
        value = value[part]
    return not isinstance(value, dict)


def _all_steps(steps: list[StepSpec]) -> Iterator[StepSpec]:
    for step in steps:
        yield step
        yield from step.between


def _check_pattern(task: LoadedTask, pattern: Pattern, path: PathKey, report: Report) -> None:
    params = task.task.params
    if pattern.index not in params:
        report.error(path + ("index",), unknown_name("param", pattern.index, params))
        return
    param = params[pattern.index]
    if param.type != "int":
        report.error(
            path + ("index",),
            f"pattern index param {pattern.index!r} must be of type int, not {param.type}",
        )
        return
    lo = param.min if param.min is not None else None
    hi = param.max if param.max is not None else None
    if lo is None or hi is None:
        report.error(
            ("params", pattern.index),
            f"param {pattern.index!r} indexes a pattern and needs "
            f"min and max (0..{pattern.slots - 1})",
            at_key=True,
        )
    elif lo < 0 or hi > pattern.slots - 1:
        grid = " x ".join(str(g) for g in pattern.grid)
        report.error(
            ("params", pattern.index),
            f"param {pattern.index!r} range [{lo:g}, {hi:g}] "
            f"does not fit the {grid} pattern's slots 0..{pattern.slots - 1}",
            at_key=True,
        )


def _check_change_tool(cell: Cell, tool: str, path: PathKey, report: Report) -> None:
    if tool not in cell.tools:
        known = list(cell.tools)
        report.error(
            path + ("tool",) if not _is_short(report, path) else path,
            unknown_name("tool", tool, known)
            if known
            else f"unknown tool {tool!r}: the cell has no 'tools:' to change between",
        )
    elif cell.tool_changer is None:
        report.error(
            path,
            f"change_tool needs the cell's tool_changer: {{lock: OUTPUT, locked: INPUT, "
            f"rack: {{NAME: FRAME}}}}; cell {cell.cell!r} has none",
        )


def _check_tool_at_end(task: LoadedTask, cell: Cell, report: Report) -> None:
    """Every job starts with ``robot.tool`` mounted, so a task must end with it."""
    last = None
    for step in task.steps:
        if step.kind == StepKind.CHANGE_TOOL and step.args.tool in cell.tools:
            last = step
    if last is not None and last.args.tool != cell.robot.tool:
        report.error(
            last.path,
            f"the task ends with tool {last.args.tool!r} mounted, but every job starts "
            f"with {cell.robot.tool!r} (robot.tool); add 'change_tool: {cell.robot.tool}' before the end",
        )


def _check_param_camera(cell: Cell, name: str, camera: str, report: Report) -> None:
    cameras = cell.cameras
    path = ("params", name, "camera")
    if camera not in cameras:
        report.error(path, unknown_name("camera", camera, cameras))
    elif cameras[camera].mount == "flange":
        report.error(
            path,
            f"camera {camera!r} rides on the flange: where it saw the part depends on where the "
            "arm stood; give the pose in a frame (or use a camera fixed in the world)",
        )


def _check_pose_param(
    task: LoadedTask, cell: Cell, name: str, path: PathKey, report: Report
) -> None:
    params = task.task.params
    if name not in params:
        report.error(path, unknown_name("param", name, params))
    elif params[name].type != "pose":
        report.error(path, f"offset param {name!r} must be of type pose, not {params[name].type}")
    elif (camera := params[name].camera) is not None:
        _check_param_camera(cell, name, camera, report)


def _check_align(task: LoadedTask, cell: Cell, step: StepSpec, report: Report) -> None:
    """An align names a camera of the cell and is followed by a step aimed at a frame."""
    from cellrunner.model.align import aligned_frame

    if step.args.camera not in cell.cameras:
        report.error(
            step.path + ("camera",), unknown_name("camera", step.args.camera, list(cell.cameras))
        )
    at = next((i for i, s in enumerate(task.steps) if s is step), None)
    if at is None:
        report.error(step.path, "align belongs in the task's steps (not on_error, not a retry)")
    elif aligned_frame(task.steps, at) is None:
        report.error(
            step.path,
            "align must come before a step aimed at a frame (pick, place, approach, descend, "
            "linear, insert or move to a frame): the marker's pose is given in that frame",
        )
