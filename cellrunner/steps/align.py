"""``align``: look at an ArUco marker on the part at the next step's frame and correct the
TCP until the marker is where that frame says (:mod:`cellrunner.execution.align` runs it);
later steps aimed at the frame move with the correction."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.align import AlignArgs, aligned_frame
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.marker import Marker
from cellrunner.model.step import Macro, Step, StepKind
from cellrunner.model.step_kinds import StepKindDef, register
from cellrunner.model.task import MoveArgs

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.execution.context import JobContext
    from cellrunner.execution.outcome import StepGen
    from cellrunner.model.camera import Camera
    from cellrunner.model.expand import Expansion
    from cellrunner.model.loaded import StepSpec
    from cellrunner.model.references import ReferenceCheck
    from cellrunner.planning.task_plan import StepPlan, StepPlanner

#: an align's look: the marker spans this share of the picture's height, from at least
#: this far (m)
LOOK_SPAN, LOOK_MIN_M = 0.10, 0.1
#: the planned time of an align step: one look, its detection, no move (s)
ALIGN_LOOK_S = 0.5


@register
class Align(StepKindDef):
    name = "align"
    order = 16
    args = AlignArgs
    top_level_only = True
    summary = (
        "Look at an ArUco marker on the part at the next step's frame and correct the TCP "
        "until the marker is where that frame says; later steps aimed at the frame move "
        "with the correction; beyond `max_correction` the step fails (3)."
    )
    example: ClassVar[Any] = {
        "camera": "wrist",
        "marker": {"dictionary": "DICT_4X4_50", "id": 7, "size": 0.03},
        "tolerance": {"xyz": 0.001, "rpy": 0.5},
        "max_correction": {"xyz": [0.015, 0.015, 0], "rpy": [0, 0, 8]},
        "attempts": 3,
    }

    def expand(self, builder: Expansion, spec: StepSpec, args: Any) -> None:
        """The look (a camera on the flange moves to see the marker) and the align, which
        corrects its frame for the steps after it."""
        import numpy as np

        from cellrunner.model import geometry
        from cellrunner.model.expand import ALIGN_KEY
        from cellrunner.model.frames import frame_pose
        from cellrunner.model.marker_place import marker_in_frame

        frame = aligned_frame(builder.task_steps, builder.position)
        assert frame is not None  # references checked it
        cell = builder.cell
        # the marker in the target frame: an id resolved on the part (or fixture) carrying it
        marker = marker_in_frame(cell, frame, spec.args.marker)
        args = spec.args.model_copy(update={"marker": marker})
        camera = cell.cameras[args.camera]
        tcp = cell.tool.tcp.matrix() if cell.tool is not None else np.eye(4)
        extra = {
            "T_world_frame": frame_pose(cell, frame),
            "T_marker": args.marker.pose.matrix(),
            "K": camera.intrinsics.matrix(),
            "distortion": np.asarray(camera.intrinsics.distortion, float),
            # the camera on the flange: seen from the TCP; else fixed in the world
            "T_tcp_camera": np.linalg.inv(tcp) @ camera.pose.matrix()
            if camera.eye_in_hand
            else None,
            "T_world_camera": None if camera.eye_in_hand else builder.camera_pose(args.camera),
        }
        macro = Macro("align", frame)
        if camera.eye_in_hand and args.look:
            look = _look_pose(args, camera, extra)
            builder.steps.append(
                Step(
                    builder.next_index(),
                    StepKind.MOVE,
                    frame,
                    MoveArgs(to=frame),
                    spec.path,
                    macro,
                    look,
                )
            )
        extra["marker_id_given"] = not isinstance(spec.args.marker, Marker)
        # the correction check plans this job with (align:FRAME): its correcting line
        correction = builder.params.get(ALIGN_KEY + frame)
        extra["correction"] = (
            None
            if correction is None
            else geometry.pose_matrix(correction["xyz"], correction["rpy"])
        )
        builder.steps.append(
            Step(builder.next_index(), StepKind.ALIGN, frame, args, spec.path, macro, extra=extra)
        )
        builder.aligned.add(frame)

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        """An align names a camera of the cell and is followed by a step aimed at a frame."""
        report, cameras = refs.report, refs.cell.cameras
        if spec.args.camera not in cameras:
            report.error(
                spec.path + ("camera",), unknown_name("camera", spec.args.camera, list(cameras))
            )
        steps = refs.task.steps
        at = next((i for i, s in enumerate(steps) if s is spec), None)
        if at is None:
            report.error(spec.path, "align belongs in the task's steps (not on_error, not a retry)")
        elif aligned_frame(steps, at) is None:
            report.error(
                spec.path,
                "align must come before a step aimed at a frame (pick, place, approach, descend, "
                "linear, insert or move to a frame): the marker's pose is given in that frame",
            )
        elif not isinstance(spec.args.marker, Marker):
            _check_marker_id(refs, spec, aligned_frame(steps, at) or "")

    def plan(self, planner: StepPlanner, row: StepPlan) -> None:
        from cellrunner.planning.align_proof import prove_align, prove_correcting_line

        step = row.step
        prove_align(planner, step)
        prove_correcting_line(planner, step)
        row.duration_s = ALIGN_LOOK_S
        row.message = (
            f"looks at marker {step.args.marker.id} up to {step.args.attempts} times; "
            f"corrections within the max_correction box are checked as align:{step.name}"
        )

    def run(self, ctx: JobContext, step: Step, resume: bool) -> StepGen:
        from cellrunner.execution.align import run_align

        return run_align(ctx, step)


def _check_marker_id(refs: ReferenceCheck, spec: Any, frame: str) -> None:
    """``marker: ID`` names a marker the part at the target frame, or a fixture, carries."""
    from cellrunner.model.marker_place import find_marker, part_at

    cell = refs.cell
    if find_marker(cell, frame, spec.args.marker) is not None:
        return
    part = part_at(cell, frame)
    known = [m.id for m in part.markers] if part is not None else []
    known += [m.id for f in cell.fixtures for m in f.markers]
    where = (
        f"part {part.name!r} at frame {frame!r}" if part is not None else f"no part at {frame!r}"
    )
    refs.report.error(
        spec.path + ("marker",),
        f"marker {spec.args.marker} is printed on no part or fixture ({where}); markers "
        f"there and on the fixtures: {', '.join(map(str, sorted(known))) or '(none)'}; "
        "a part's or fixture's `markers:` puts one there",
    )


def _look_pose(args: AlignArgs, camera: Camera, extra: dict[str, Any]) -> np.ndarray:
    """T_world_tcp with the camera on the marker's axis, ``standoff`` out from its face,
    looking at it (the camera's X along the marker's X)."""
    import numpy as np

    from cellrunner.model import geometry

    fy, height = camera.intrinsics.fy, camera.image_size[1]
    assert isinstance(args.marker, Marker)  # resolved on its carrier by expand
    standoff = args.standoff or max(LOOK_MIN_M, fy * args.marker.size / (LOOK_SPAN * height))
    T_world_camera = (
        extra["T_world_frame"]
        @ extra["T_marker"]
        @ geometry.pose_matrix((0, 0, standoff), (180, 0, 0))
    )
    return np.asarray(T_world_camera @ np.linalg.inv(extra["T_tcp_camera"]))
