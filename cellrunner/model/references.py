"""Checks of a task's references against its cell: frames, IO names, params, patterns."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from cellrunner.model.checks import check_io_name
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.step import StepKind
from cellrunner.model.step_kinds import kind_of

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.model.loaded import LoadedCell, LoadedTask, StepSpec
    from cellrunner.model.pattern import Pattern
    from cellrunner.model.report import Report
    from cellrunner.model.source import PathKey


class ReferenceCheck:
    """What a kind's reference check (:meth:`StepKindDef.check_references`) works with: the
    task, its cell, the report the errors go to, and the checks steps share."""

    def __init__(self, task: LoadedTask, cell: Cell, report: Report) -> None:
        self.task, self.cell, self.report = task, cell, report
        self.frames = list(cell.frames)
        #: a step grips or releases: the cell needs a gripper
        self.needs_gripper = False

    def is_short(self, path: PathKey) -> bool:
        """True when the step at ``path`` was written in short form (``move: [..]``)."""
        return _is_short(self.report, path)

    def frame(self, name: str, path: PathKey) -> None:
        if name not in self.cell.frames:
            self.report.error(path, unknown_name("frame", name, self.frames))

    def contacts(self, args: Any, path: PathKey) -> None:
        """The fixtures a line's ``contact:`` names exist."""
        fixtures = [f.name for f in self.cell.fixtures]
        for i, name in enumerate(getattr(args, "contact", None) or ()):
            if name not in fixtures:
                self.report.error(path + ("contact", i), unknown_name("fixture", name, fixtures))

    def at_frame(self, spec: StepSpec) -> None:
        """A pick's or place's ``at``: its frame, pattern and pose param."""
        args, path = spec.args, spec.path
        self.frame(args.at, path + ("at",))
        if args.pattern is not None:
            _check_pattern(self.task, args.pattern, path + ("pattern",), self.report)
        if args.at_offset is not None:
            _check_pose_param(
                self.task, self.cell, args.at_offset, path + ("at", "offset"), self.report
            )

    def input(self, name: str, path: PathKey) -> None:
        check_io_name(self.cell, name, "inputs", path, self.report)

    def output(self, name: str, path: PathKey) -> None:
        check_io_name(self.cell, name, "outputs", path, self.report, at_key=True)


def check_task_references(task: LoadedTask, loaded: LoadedCell, report: Report) -> None:
    cell = loaded.cell
    refs = ReferenceCheck(task, cell, report)
    for step in _all_steps([*task.steps, *task.on_error]):
        kind, args, path = kind_of(step.kind), step.args, step.path
        if getattr(args, "pattern", None) is not None and not kind.macro:
            if kind.target_frame(args) is None:
                report.error(
                    path + ("pattern",), "a pattern offsets a frame; this move's target is not one"
                )
            else:
                _check_pattern(task, args.pattern, path + ("pattern",), report)
        kind.check_references(refs, step)
    _check_tool_at_end(task, cell, report)
    if refs.needs_gripper and cell.tool.gripper is None:
        report.error(
            ("steps",), f"the task grips and releases but cell {cell.cell!r} has no tool.gripper"
        )
    for name, param in task.task.params.items():
        for i, choice in enumerate(param.choices or ()):
            if choice not in cell.frames:
                report.error(
                    ("params", name, "choices", i), unknown_name("frame", choice, refs.frames)
                )
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
        dims = [*pattern.grid, *([pattern.layers] if pattern.layers else [])]
        grid = " x ".join(str(g) for g in dims)
        report.error(
            ("params", pattern.index),
            f"param {pattern.index!r} range [{lo:g}, {hi:g}] "
            f"does not fit the {grid} pattern's slots 0..{pattern.slots - 1}",
            at_key=True,
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
