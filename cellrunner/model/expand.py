"""Expanding a task into primitive steps for given params.

``pick`` -> approach, descend, grip (with the retry plan), lift;
``place`` -> approach, descend, release, retreat. Frame targets are resolved to world
poses of the TCP here (frames, offsets in the target frame's axes, pattern slots), so
planning and execution work from one list of :class:`Step` objects.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cellrunner.errors import InputError
from cellrunner.model import geometry
from cellrunner.model.align import AlignArgs, aligned_frame, target_frame
from cellrunner.model.camera import Camera
from cellrunner.model.cell import Cell
from cellrunner.model.frames import frame_pose
from cellrunner.model.loaded import LoadedTask, StepSpec
from cellrunner.model.params import Param, ParamValue, PoseValue
from cellrunner.model.pattern import Pattern
from cellrunner.model.source import PathKey
from cellrunner.model.step import (
    LINEAR_KINDS,
    MOTION_KINDS,
    PLANNED_KINDS,
    RetryPlan,
    Step,
    StepKind,
)
from cellrunner.model.task import (
    ApproachArgs,
    DistanceArgs,
    GripArgs,
    LinearArgs,
    MoveArgs,
    Offset,
    PickArgs,
    PlaceArgs,
    TaskFile,
)
from cellrunner.model.tool_change import expand_change_tool


def camera_pose(cell: Cell, name: str) -> np.ndarray:
    """T_world_camera of a camera fixed in the world or on a frame (the camera frame is
    OpenCV's: Z out of the lens, X right, Y down)."""
    camera = cell.cameras[name]
    if camera.mount == "world":
        return camera.pose.matrix()
    return np.asarray(frame_pose(cell, camera.mount) @ camera.pose.matrix())


def resolve_params(task: TaskFile, given: dict[str, Any]) -> dict[str, ParamValue]:
    """The task's params: defaults overridden by ``given`` (strings from the CLI are
    accepted); raises InputError naming the bad param and its bounds."""
    out: dict[str, ParamValue] = {}
    problems = []
    for name in given:
        if name not in task.params:
            problems.append(f"unknown param {name!r}; known: {', '.join(task.params) or '(none)'}")
    for name, param in task.params.items():
        value = given.get(name, param.default)
        try:
            out[name] = param.coerce(name, value)
        except ValueError as exc:
            problems.append(str(exc))
    if problems:
        raise InputError("; ".join(problems), "<params>")
    return out


def expand(loaded: LoadedTask, cell: Cell, params: dict[str, Any]) -> list[Step]:
    """The primitive steps of ``loaded`` for ``params`` (already resolved)."""
    builder = _Builder(cell, params, loaded.task.params)
    for i, spec in enumerate(loaded.steps):
        if spec.kind == StepKind.ALIGN:
            builder.align(spec, aligned_frame(loaded.steps, i))
        else:
            builder.add(spec)
    return builder.steps


#: an align's look: the marker spans this share of the picture's height, from at least
#: this far (m)
LOOK_SPAN, LOOK_MIN_M = 0.10, 0.1

#: the key of an align's correction among the params (``align:FRAME``): a pose
#: ``{xyz, rpy}`` in the frame's axes; ``check`` plans the corners of its box, a job
#: the correction the align step measured
ALIGN_KEY = "align:"


def expand_on_error(
    loaded: LoadedTask, cell: Cell, params: dict[str, Any], first_index: int
) -> list[Step]:
    """The task's ``on_error`` steps, numbered from ``first_index``, marked with the macro
    ``on_error`` (the job runner keeps them for after a failure)."""
    builder = _Builder(cell, params, loaded.task.params)
    return [
        builder.primitive(
            s.kind, s.bind(loaded.task.params, params), s.path, first_index + i, ON_ERROR
        )
        for i, s in enumerate(loaded.on_error)
    ]


ON_ERROR = "on_error"


class _Builder:
    def __init__(
        self, cell: Cell, params: dict[str, Any], specs: dict[str, Param] | None = None
    ) -> None:
        self.cell, self.params, self.specs = cell, params, specs or {}
        self.steps: list[Step] = []
        self.tool = cell.robot.tool  # the mounted tool's name (with ``tools:``)
        self.aligned: set[str] = set()  # frames an align step before corrects

    def align(self, spec: StepSpec, frame: str | None) -> None:
        """An align step: it corrects ``frame`` for the steps after it."""
        assert frame is not None  # references checked it
        args = spec.args
        camera = self.cell.cameras[args.camera]
        tcp = self.cell.tool.tcp.matrix() if self.cell.tool is not None else np.eye(4)
        extra = {
            "T_world_frame": frame_pose(self.cell, frame),
            "T_marker": args.marker.pose.matrix(),
            "K": camera.intrinsics.matrix(),
            "distortion": np.asarray(camera.intrinsics.distortion, float),
            # the camera on the flange: seen from the TCP; else fixed in the world
            "T_tcp_camera": np.linalg.inv(tcp) @ camera.pose.matrix()
            if camera.eye_in_hand
            else None,
            "T_world_camera": None if camera.eye_in_hand else camera_pose(self.cell, args.camera),
        }
        macro = f"align {frame}"
        if camera.eye_in_hand and args.look:
            self.steps.append(
                Step(
                    self._next(),
                    StepKind.MOVE,
                    frame,
                    MoveArgs(to=frame),
                    spec.path,
                    macro,
                    self._look_pose(args, camera, extra),
                )
            )
        self.steps.append(
            Step(self._next(), StepKind.ALIGN, frame, args, spec.path, macro, extra=extra)
        )
        self.aligned.add(frame)

    def _look_pose(self, args: AlignArgs, camera: Camera, extra: dict[str, Any]) -> np.ndarray:
        """T_world_tcp with the camera on the marker's axis, ``standoff`` out from its
        face, looking at it (the camera's X along the marker's X)."""
        fy, height = camera.intrinsics.fy, camera.image_size[1]
        standoff = args.standoff or max(LOOK_MIN_M, fy * args.marker.size / (LOOK_SPAN * height))
        T_world_camera = (
            extra["T_world_frame"]
            @ extra["T_marker"]
            @ geometry.pose_matrix((0, 0, standoff), (180, 0, 0))
        )
        return np.asarray(T_world_camera @ np.linalg.inv(extra["T_tcp_camera"]))

    def _frame(self, name: str) -> np.ndarray:
        """The frame's pose, with the correction of an align before (``align:FRAME``)."""
        T = frame_pose(self.cell, name)
        correction = self.params.get(ALIGN_KEY + name) if name in self.aligned else None
        if correction is not None:
            T = T @ geometry.pose_matrix(correction["xyz"], correction["rpy"])
        return T

    def _next(self) -> int:
        return len(self.steps) + 1

    def add(self, spec: StepSpec) -> None:
        first = len(self.steps)
        self._add(spec)
        frame = target_frame(spec)
        if frame in self.aligned:  # the job corrects these targets by what the align measured
            for step in self.steps[first:]:
                if step.T_world_tcp is not None:
                    step.extra["aligned_frame"] = frame
                    step.extra["T_world_frame"] = frame_pose(self.cell, frame)

    def _add(self, spec: StepSpec) -> None:
        kind, args = spec.kind, spec.bind(self.specs, self.params)
        if kind == StepKind.PICK:
            self._pick(spec, args)
        elif kind == StepKind.PLACE:
            self._place(spec, args)
        elif kind == StepKind.CHANGE_TOOL:
            steps, self.tool = expand_change_tool(self.cell, spec, self.tool, self._next())
            self.steps.extend(steps)
        else:
            self.steps.append(self.primitive(kind, args, spec.path, self._next()))

    def primitive(
        self,
        kind: str,
        args: Any,
        path: PathKey,
        index: int,
        macro: str | None = None,
        retry: RetryPlan | None = None,
    ) -> Step:
        name, T, q = kind, None, None
        if kind == StepKind.MOVE:
            if isinstance(args.to, list):
                name, q = "joints", tuple(args.to)
            elif args.to == "home":
                name, q = "home", tuple(self.cell.robot.home)
            else:
                T, name = self._target(args.to, args.offset, args.pattern)
        elif kind == StepKind.APPROACH:
            T, name = self._target(args.to, args.offset, args.pattern)
            T = T @ geometry.pose_matrix((0, 0, -args.distance))
        elif kind in (StepKind.DESCEND, StepKind.LINEAR):
            T, name = self._target(args.to, args.offset, args.pattern)
        elif kind == StepKind.INSERT:  # the line ends ``depth`` past the frame, along its Z
            T, name = self._target(args.to, None, args.pattern)
            T = T @ geometry.pose_matrix((0, 0, args.depth))
        elif kind == StepKind.SET_OUTPUT:
            name = ", ".join(f"{k}={v}" for k, v in args.values.items())
        elif kind == StepKind.WAIT_INPUT:
            name = args.input
        elif kind == StepKind.WAIT:
            name = f"{args.seconds:g} s"
        return Step(index, StepKind(kind), name, args, path, macro, T, q, retry)

    def _target(
        self, at: str, offset: Offset | None, pattern: Pattern | None, at_offset: str | None = None
    ) -> tuple[np.ndarray, str]:
        T = self._frame(at)
        name = at
        if pattern is not None:
            slot = int(self.params[pattern.index])
            dx, dy, dz, _ = pattern.offset_m(slot)
            T = geometry.pose_matrix((0, 0, dz)) @ T @ geometry.pose_matrix((dx, dy, 0))
            name = f"{at}[{pattern.index}={slot}]"
        if (
            at_offset is not None
        ):  # a pose param: where the camera saw the part, in the frame's axes
            pose = self.params[at_offset]
            camera = self.specs[at_offset].camera if at_offset in self.specs else None
            T_pose = geometry.pose_matrix(pose["xyz"], pose["rpy"])
            # a camera's detection: where the camera saw the part, through its pose
            T = camera_pose(self.cell, camera) @ T_pose if camera is not None else T @ T_pose
            name = f"{at}+{at_offset}"
        return T @ _offset(offset), name

    def _part_pose(self, at: str, pattern: Pattern | None) -> dict[str, np.ndarray]:
        """Where the part a pick from a pattern grips lies: its slot of the frame
        (``part_pose``, world); nothing for a pick from the frame itself."""
        if pattern is None:
            return {}
        return {"part_pose": self._target(at, None, pattern)[0]}

    def _pick(self, spec: StepSpec, a: PickArgs) -> None:
        T, name = self._target(a.at, a.offset, a.pattern, a.at_offset)
        macro = f"pick {name}"
        path = spec.path
        approach_i = self._next()
        self.steps.append(
            Step(
                approach_i,
                StepKind.APPROACH,
                name,
                ApproachArgs(to=a.at, distance=a.approach),
                path,
                macro,
                T @ geometry.pose_matrix((0, 0, -a.approach)),
            )
        )
        descend_i = self._next()
        self.steps.append(
            Step(
                descend_i,
                StepKind.DESCEND,
                name,
                LinearArgs(to=a.at, speed=a.speed),
                path,
                macro,
                T,
            )
        )
        retry = None
        if a.retry is not None and a.retry.attempts > 1:
            between = tuple(
                self.primitive(
                    s.kind, s.bind(self.specs, self.params), s.path, descend_i + 1, macro
                )
                for s in spec.between
            )
            retry = RetryPlan(a.retry.attempts, between, descend_i)
        self.steps.append(
            Step(
                self._next(),
                StepKind.GRIP,
                name,
                a.grip,
                path,
                macro,
                retry=retry,
                extra={"part_at": a.at, **self._part_pose(a.at, a.pattern)},
            )
        )
        lift = a.lift if a.lift is not None else a.approach
        if lift > 0:
            self.steps.append(
                Step(
                    self._next(),
                    StepKind.LIFT,
                    name,
                    DistanceArgs(distance=lift, speed=a.speed),
                    path,
                    macro,
                )
            )

    def _earlier_slots(self, a: PlaceArgs) -> list[np.ndarray]:
        return _earlier_slots_of(self, a)

    def _place(self, spec: StepSpec, a: PlaceArgs) -> None:
        T, name = self._target(a.at, a.offset, a.pattern, a.at_offset)
        macro = f"place {name}"
        path = spec.path
        self.steps.append(
            Step(
                self._next(),
                StepKind.APPROACH,
                name,
                ApproachArgs(to=a.at, distance=a.approach),
                path,
                macro,
                T @ geometry.pose_matrix((0, 0, -a.approach)),
            )
        )
        self.steps.append(
            Step(
                self._next(),
                StepKind.DESCEND,
                name,
                LinearArgs(to=a.at, speed=a.speed),
                path,
                macro,
                T,
            )
        )
        release = (
            a.release if a.confirm is None else a.release.model_copy(update={"confirm": a.confirm})
        )
        tolerance = self.cell.place_tolerance
        # the twin compares the part's pose with this once the gripper has left it
        check = {
            "place_check": {"T_world_tcp": T, "tolerance": (tolerance.distance, tolerance.angle)}
        }
        # where the earlier slots of its pattern put their parts (what this one may rest on)
        earlier = self._earlier_slots(a)
        back = a.retreat if a.retreat is not None else a.approach
        self.steps.append(
            Step(
                self._next(),
                StepKind.RELEASE,
                name,
                release,
                path,
                macro,
                extra={"earlier_slots": earlier, **({} if back > 0 else check)},
            )
        )
        if back > 0:
            self.steps.append(
                Step(
                    self._next(),
                    StepKind.RETREAT,
                    name,
                    DistanceArgs(distance=back, speed=a.speed),
                    path,
                    macro,
                    extra=check,
                )
            )


def _earlier_slots_of(builder: _Builder, a: PlaceArgs) -> list[np.ndarray]:
    """The TCP targets of the slots before this one in the place's pattern (none without
    a pattern): the parts earlier jobs put there."""
    if a.pattern is None:
        return []
    slot = int(builder.params[a.pattern.index])
    out = []
    for earlier in range(slot):
        was = _Builder(builder.cell, {**builder.params, a.pattern.index: earlier}, builder.specs)
        out.append(was._target(a.at, a.offset, a.pattern, a.at_offset)[0])
    return out


def _offset(offset: Offset | None) -> np.ndarray:
    return np.eye(4) if offset is None else offset.matrix()


def pattern_params(loaded: LoadedTask) -> dict[str, range]:
    """Every param that indexes a pattern, with the slot range ``check`` must cover."""
    out: dict[str, range] = {}
    for spec in loaded.steps:
        pattern = getattr(spec.args, "pattern", None)
        if pattern is not None:
            p = loaded.task.params[pattern.index]
            out[pattern.index] = range(int(p.min), int(p.max) + 1)
    return out


def box_params(loaded: LoadedTask) -> dict[str, list[PoseValue]]:
    """Every pose param a pick or place is offset by, with the poses ``check`` must cover:
    the centre and the corners of its box; and every align's correction
    (``align:FRAME``), the centre and the corners of its ``max_correction`` box."""
    from cellrunner.model.params import box_values

    out: dict[str, list[PoseValue]] = {}
    for i, spec in enumerate(loaded.steps):
        name = getattr(spec.args, "at_offset", None)
        if name is not None:
            out[name] = loaded.task.params[name].box_values()
        if spec.kind == StepKind.ALIGN:
            frame = aligned_frame(loaded.steps, i)
            if frame is not None:
                out[ALIGN_KEY + frame] = box_values(*spec.args.box())
    return out


#: float param kinds that change what the arm does in space (a wait's time or a force limit
#: does not change a plan; a param with no unit might)
MOTION_FLOAT_KINDS = (None, "length", "angle", "speed")


def float_params(loaded: LoadedTask) -> dict[str, list[float]]:
    """Every bounded float param that may change a motion (a length, an angle, a speed, or
    no unit), with the values ``check`` must cover: its range's ends and centre, as a pose
    param's box (a float param without both bounds has no range to prove)."""
    out: dict[str, list[float]] = {}
    for name, p in loaded.task.params.items():
        bounded = p.min is not None and p.max is not None
        if p.type == "float" and p.kind in MOTION_FLOAT_KINDS and bounded:
            lo, hi = float(p.min), float(p.max)
            out[name] = sorted({lo, (lo + hi) / 2, hi})
    return out


def frame_params(loaded: LoadedTask) -> dict[str, list[str]]:
    """Every frame param, with the choices ``check`` must cover (every one)."""
    return {
        name: list(p.choices or []) for name, p in loaded.task.params.items() if p.type == "frame"
    }


__all__ = [
    "ALIGN_KEY",
    "LINEAR_KINDS",
    "MOTION_KINDS",
    "ON_ERROR",
    "PLANNED_KINDS",
    "GripArgs",
    "RetryPlan",
    "Step",
    "StepKind",
    "aligned_frame",
    "box_params",
    "camera_pose",
    "expand",
    "expand_on_error",
    "float_params",
    "frame_params",
    "frame_pose",
    "pattern_params",
    "resolve_params",
]
