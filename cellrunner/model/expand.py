"""Expanding a task into primitive steps for given params.

``pick`` -> approach, descend, grip (with the retry plan), lift;
``place`` -> approach, descend, release, retreat. Frame targets are resolved to world
poses of the TCP here (frames, offsets in the target frame's axes, pattern slots), so
planning and execution work from one list of :class:`Step` objects.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cellrunner.errors import InputError
from cellrunner.model import geometry
from cellrunner.model.align import aligned_frame
from cellrunner.model.cell import Cell
from cellrunner.model.frames import frame_pose
from cellrunner.model.loaded import LoadedTask, StepSpec
from cellrunner.model.params import Param, ParamValue, PoseValue
from cellrunner.model.pattern import Pattern
from cellrunner.model.source import PathKey
from cellrunner.model.step import Macro, RetryPlan, Step, StepKind
from cellrunner.model.step_kinds import kind_of
from cellrunner.model.task import ApproachArgs, GripArgs, LinearArgs, Offset, TaskFile


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
    builder = Expansion(cell, params, loaded.task.params, loaded.steps)
    for i, spec in enumerate(loaded.steps):
        builder.position = i
        builder.add(spec)
    return builder.steps


#: the key of an align's correction among the params (``align:FRAME``): a pose
#: ``{xyz, rpy}`` in the frame's axes; ``check`` plans the corners of its box, a job
#: the correction the align step measured
ALIGN_KEY = "align:"


def expand_on_error(
    loaded: LoadedTask, cell: Cell, params: dict[str, Any], first_index: int
) -> list[Step]:
    """The task's ``on_error`` steps, numbered from ``first_index``, marked with the macro
    ``on_error`` (the job runner keeps them for after a failure)."""
    builder = Expansion(cell, params, loaded.task.params)
    return [
        builder.primitive(
            s.kind, s.bind(loaded.task.params, params), s.path, first_index + i, ON_ERROR
        )
        for i, s in enumerate(loaded.on_error)
    ]


ON_ERROR = Macro("on_error")


class Expansion:
    """A job's steps as they are expanded, and what each kind's expansion
    (:meth:`~cellrunner.model.step_kinds.StepKindDef.expand`) needs: the cell, the params,
    targets resolved to TCP poses, the tool mounted so far and the frames aligned so far."""

    def __init__(
        self,
        cell: Cell,
        params: dict[str, Any],
        specs: dict[str, Param] | None = None,
        task_steps: list[StepSpec] | None = None,
    ) -> None:
        self.cell, self.params, self.specs = cell, params, specs or {}
        self.steps: list[Step] = []
        self.tool = cell.robot.tool  # the mounted tool's name (with ``tools:``)
        self.aligned: set[str] = set()  # frames an align step before corrects
        #: the task's steps as written, and the index of the one being expanded
        self.task_steps: list[StepSpec] = task_steps or []
        self.position = 0

    def with_params(self, params: dict[str, Any]) -> Expansion:
        """A fresh expansion of the same cell and task for other param values."""
        return Expansion(self.cell, params, self.specs, self.task_steps)

    def _frame(self, name: str) -> np.ndarray:
        """The frame's pose, with the correction of an align before (``align:FRAME``)."""
        T = frame_pose(self.cell, name)
        correction = self.params.get(ALIGN_KEY + name) if name in self.aligned else None
        if correction is not None:
            T = T @ geometry.pose_matrix(correction["xyz"], correction["rpy"])
        return T

    def next_index(self) -> int:
        """The 1-based index the next expanded step takes."""
        return len(self.steps) + 1

    def camera_pose(self, name: str) -> np.ndarray:
        return camera_pose(self.cell, name)

    def add(self, spec: StepSpec) -> None:
        first = len(self.steps)
        kind = kind_of(spec.kind)
        kind.expand(self, spec, spec.bind(self.specs, self.params))
        frame = kind.target_frame(spec.args)
        if frame in self.aligned:  # the job corrects these targets by what the align measured
            for step in self.steps[first:]:
                if step.T_world_tcp is not None:
                    step.extra["aligned_frame"] = frame
                    step.extra["T_world_frame"] = frame_pose(self.cell, frame)

    def approach_and_descend(
        self, a: Any, T_world_tcp: np.ndarray, name: str, path: PathKey, macro: str
    ) -> None:
        """A pick's or place's way down to ``T_world_tcp`` (its ``at``): a planned approach
        to ``a.approach`` above it along its Z, then a straight descend at ``a.speed``."""
        approach = ApproachArgs(to=a.at, distance=a.approach)
        T_above = T_world_tcp @ geometry.pose_matrix((0, 0, -a.approach))
        index = self.next_index()
        self.steps.append(Step(index, StepKind.APPROACH, name, approach, path, macro, T_above))
        descend = LinearArgs(to=a.at, speed=a.speed)
        self.steps.append(
            Step(index + 1, StepKind.DESCEND, name, descend, path, macro, T_world_tcp)
        )

    def primitive(
        self,
        kind: str,
        args: Any,
        path: PathKey,
        index: int,
        macro: str | None = None,
        retry: RetryPlan | None = None,
    ) -> Step:
        name, T, q = kind_of(kind).target(self, args)
        return Step(index, kind, name, args, path, macro, T, q, retry)

    def target(
        self, at: str, offset: Offset | None, pattern: Pattern | None, at_offset: str | None = None
    ) -> tuple[np.ndarray, str]:
        T = self._frame(at)
        name = at
        if pattern is not None:
            slot = int(self.params[pattern.index])
            dz = pattern.offset_m(slot)[2]
            T = geometry.pose_matrix((0, 0, dz)) @ T @ pattern.T_frame_slot(slot)
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

    def part_pose(
        self, at: str, pattern: Pattern | None, at_offset: str | None = None
    ) -> dict[str, np.ndarray]:
        """Where the part a pick grips lies (``part_pose``, world): its slot of a pattern,
        or where the pose param ``at_offset`` (a camera's detection) says it is; nothing
        for a pick from the frame itself."""
        if pattern is None and at_offset is None:
            return {}
        T_world_frame = self.target(at, None, pattern)[0]
        if at_offset is None:
            return {"part_pose": T_world_frame}
        # the part rests on what its frame stands on: the detection moves it across the
        # frame's XY plane and turns it about the frame's Z; its height and tilt out of that
        # plane are the camera's error (a box given in a tilted camera's axes leaves the plane)
        T_frame_seen = geometry.invert(T_world_frame) @ self.target(at, None, pattern, at_offset)[0]
        yaw_rad = math.atan2(T_frame_seen[1, 0], T_frame_seen[0, 0])
        T_frame_part = geometry.pose_matrix(
            (T_frame_seen[0, 3], T_frame_seen[1, 3], 0.0), (0.0, 0.0, math.degrees(yaw_rad))
        )
        return {"part_pose": T_world_frame @ T_frame_part}


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
    "ON_ERROR",
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
