"""``check`` proves an ``align`` can do its work (SPEC sections 12 and 13), once per step
whatever correction the job is planned with (one error per cause):

- **the marker is on what carries it**: an inline marker lies on the surface of the part
  waiting at the target (a marker written 20 mm above its part would be read there, and
  every part then placed 20 mm off); a marker named by id was checked where the cell
  file gives it;
- **the camera sees the whole marker**, with a margin, from where it looks, for the
  centre and every corner of ``max_correction`` (the part may lie anywhere in that box);
- **the correcting line** the run time makes at the look for the correction the job is
  planned with is planned and verified as the run time plans it
  (:func:`prove_correcting_line`, :mod:`.align_correction`);
- **one look is sure enough**: the pose noise predicted from the marker's size, the
  standoff and the focal length (:mod:`.marker_noise`) fits the step's tolerance with
  the axes it reads.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.model.failure import Failure, FailureKind

if TYPE_CHECKING:
    from collections.abc import Callable

    from cellrunner.model.camera import Camera
    from cellrunner.model.step import Step
    from cellrunner.planning.task_plan import StepPlanner


def prove_align(planner: StepPlanner, step: Step) -> None:
    """Raise InfeasibleError when the align at ``step`` cannot see or read its marker,
    or its marker lies off its part; the arm stands at ``planner.q`` (the look)."""
    cell = planner.world.loaded.cell
    camera = cell.cameras[step.args.camera]
    if not step.extra.get("marker_id_given", False):
        _on_its_part(planner, step)
    T_world_camera = (
        planner.world.kinematics.T_world_tcp(planner.q) @ step.extra["T_tcp_camera"]
        if step.extra["T_tcp_camera"] is not None
        else step.extra["T_world_camera"]
    )
    _sees_marker(step, camera, T_world_camera)
    _nothing_in_the_way(planner, step, T_world_camera)
    _reads_within_tolerance(step, camera, T_world_camera)


def _on_its_part(planner: StepPlanner, step: Step) -> None:
    """An inline marker lies on the surface of the part at the target frame."""
    from cellrunner.model.marker_place import inline_on_part
    from cellrunner.model.marker_surface import off_surface

    marker, frame = step.args.marker, step.name
    found = inline_on_part(planner.world.loaded.cell, frame, marker)
    if found is None:
        raise InfeasibleError(
            Failure(
                FailureKind.MARKER,
                f"marker {marker.id} is printed on nothing: no part waits at frame {frame!r}",
                fix="fix: give the part or fixture that carries it `markers:` and name it "
                "`marker: ID`",
            )
        )
    carrier, T_part_marker = found
    problem = off_surface(carrier.shape, T_part_marker, float(marker.size))
    if problem is not None:
        raise InfeasibleError(
            Failure(
                FailureKind.MARKER,
                f"marker {marker.id} is off the surface of {carrier.label}: {problem} (the "
                "camera would read the part as lying where the marker is not)",
                fix="fix: the marker's pose on the part's face (its pose is in the target "
                f"frame {frame!r}), or the part's `markers:` with `marker: ID`",
            )
        )


def _marker_corners(step: Step, C: np.ndarray) -> np.ndarray:
    """The marker's four corners in the world (4 x 3, m) with the frame corrected by C."""
    h = float(step.args.marker.size) / 2
    local = np.array([[-h, h, 0, 1], [h, h, 0, 1], [h, -h, 0, 1], [-h, -h, 0, 1]])
    T = step.extra["T_world_frame"] @ C @ step.extra["T_marker"]
    return np.asarray((local @ T.T)[:, :3])


def _corrections(step: Step) -> list[tuple[str, np.ndarray]]:
    """The centre and every corner of the step's max_correction box, named and as poses
    in the frame's axes."""
    from cellrunner.model.geometry import pose_matrix
    from cellrunner.model.params import box_values

    low, high = step.args.box()
    out = []
    for value in box_values(low, high):
        xyz, rpy = value["xyz"], value["rpy"]
        text = ", ".join(
            [f"{a} {v * 1000:+.0f} mm" for a, v in zip("xyz", xyz, strict=True) if v]
            + [f"r{a} {v:+g} deg" for a, v in zip("xyz", rpy, strict=True) if v]
        )
        out.append((text or "none", pose_matrix(xyz, rpy)))
    return out


def _sees_marker(step: Step, camera: Camera, T_world_camera: np.ndarray) -> None:
    """The camera sees the whole marker, with a margin, facing it, for every correction."""
    from cellrunner.planning.camera_view import unseen

    corrections = _corrections(step)
    missed: list[tuple[str, list[str]]] = []
    for text, C in corrections:
        corners = _marker_corners(step, C)
        why = unseen(camera, T_world_camera, corners)
        normal = (step.extra["T_world_frame"] @ C @ step.extra["T_marker"])[:3, 2]
        towards = T_world_camera[:3, 3] - corners.mean(axis=0)
        if float(np.dot(normal, towards)) <= 0:
            why.append("the marker's printed face is turned away from the camera")
        if why:
            missed.append((text, why))
    if not missed:
        return
    marker, name = step.args.marker, step.args.camera
    first_text, first_why = missed[0]
    raise InfeasibleError(
        Failure(
            FailureKind.CAMERA_VIEW,
            f"camera {name!r} does not see all of marker {marker.id} from where it looks for "
            f"{len(missed)} of the {len(corrections)} corrections max_correction allows",
            details=(f"correction {first_text}: " + "; ".join(first_why),),
            fix="fix: a look farther from the marker (standoff), a smaller max_correction, "
            "or a camera that looks at the marker's face",
        )
    )


#: points sampled along each sight line from the lens to a marker corner, and the stretch
#: before the marker left out (m: the part it is printed on lies there)
SIGHT_SAMPLES, SIGHT_END_M = 80, 0.003


def _nothing_in_the_way(planner: StepPlanner, step: Step, T_world_camera: np.ndarray) -> None:
    """No part of the tool (its geometry, open fingers and the jaws' frame the twin draws
    above them, at the look) and no fixture stands between the lens and the marker's
    corners (for the nominal correction): a wrist camera beside a wide gripper body sees
    the body, not the marker."""
    from cellrunner.model.gripper import jaw_frame_shapes
    from cellrunner.planning.sight import first_in_the_way

    world = planner.world
    T_world_flange = world.kinematics.T_world_flange(planner.q)
    tool = world.loaded.cell.tool
    drawn = [*world.tool, *jaw_frame_shapes(tool.gripper, tool.tcp.matrix())]
    bodies = [(f"tool geometry {p.name!r}", p.shape, T_world_flange @ p.T_parent_shape)
              for p in drawn]  # fmt: skip
    bodies += [(f"fixture {p.name!r}", p.shape, p.T_parent_shape) for p in world.fixtures]
    corners = _marker_corners(step, np.eye(4))
    targets = np.vstack([corners, corners.mean(axis=0)])
    hit = first_in_the_way(T_world_camera[:3, 3], targets, bodies, SIGHT_SAMPLES, SIGHT_END_M)
    if hit is None:
        return
    name, distance_m = hit
    raise InfeasibleError(
        Failure(
            FailureKind.CAMERA_VIEW,
            f"camera {step.args.camera!r} does not see marker {step.args.marker.id}: {name} "
            f"stands in its line of sight {distance_m * 1000:.0f} mm from the lens",
            fix="fix: mount the camera clear of the tool (its pose on the flange), or look "
            "from another side",
        )
    )


def _reads_within_tolerance(step: Step, camera: Camera, T_world_camera: np.ndarray) -> None:
    """One look's predicted noise fits the step's tolerance with the axes it reads."""
    from cellrunner.planning.marker_noise import ALIGN_SIGMAS, CORNER_NOISE_PX, look_noise

    args = step.args
    _, high = args.box()
    full = not (high[2] == 0 and high[3] == 0 and high[4] == 0)
    T_world_marker = step.extra["T_world_frame"] @ step.extra["T_marker"]
    standoff = float(np.linalg.norm(T_world_camera[:3, 3] - T_world_marker[:3, 3]))
    focal = math.sqrt(camera.intrinsics.fx * camera.intrinsics.fy)
    lever = float(np.linalg.norm(step.extra["T_marker"][:3, 3]))
    size = float(args.marker.size)
    tol_m, tol_rad = float(args.tolerance.xyz), math.radians(float(args.tolerance.rpy))
    noise = look_noise(size, standoff, focal, lever, full)
    if noise.within(tol_m, tol_rad):
        return
    fixes = []
    bigger = _least(
        lambda s: look_noise(s, standoff, focal, lever, full).within(tol_m, tol_rad), size
    )
    if bigger is not None:
        fixes.append(f"a bigger marker (at least {bigger * 1000:.0f} mm)")
    closer = _closest_fit(
        lambda z: look_noise(size, z, focal, lever, full).within(tol_m, tol_rad), standoff
    )
    if closer is not None:
        fixes.append(f"a closer look (standoff at most {closer * 1000:.0f} mm)")
    if full and look_noise(size, standoff, focal, lever, False).within(tol_m, tol_rad):
        fixes.append(
            "fewer axes (max_correction z, rx and ry 0: the marker is then read in its known plane)"
        )
    axes = "x, y, z, rx, ry, rz" if full else "x, y, rz"
    raise InfeasibleError(
        Failure(
            FailureKind.CAMERA_VIEW,
            f"one look of camera {args.camera!r} at marker {args.marker.id} "
            f"({size * 1000:g} mm, {noise.span_px:.0f} px wide from {standoff * 1000:.0f} mm) "
            f"reads its {axes} within {ALIGN_SIGMAS * noise.position_m * 1000:.2f} mm and "
            f"{math.degrees(ALIGN_SIGMAS * noise.rotation_rad):.2f} deg ({ALIGN_SIGMAS:g} std at "
            f"{CORNER_NOISE_PX:g} px corner noise, focal length {focal:.0f} px), over the "
            f"tolerance {tol_m * 1000:g} mm, {math.degrees(tol_rad):g} deg",
            fix="fix: " + (", or ".join(fixes) if fixes else "a looser tolerance"),
        )
    )


def _least(fits: Callable[[float], bool], size_m: float) -> float | None:
    """The smallest marker edge (m, up to 10 times ``size_m``) that ``fits``."""
    for k in range(1, 91):
        s = size_m * (1 + 0.1 * k)
        if fits(s):
            return s
    return None


def _closest_fit(fits: Callable[[float], bool], standoff_m: float) -> float | None:
    """The farthest standoff (m, down to a tenth of ``standoff_m``) that ``fits``."""
    for k in range(1, 10):
        z = standoff_m * (1 - 0.1 * k)
        if fits(z):
            return z
    return None


def prove_correcting_line(planner: StepPlanner, step: Step) -> None:
    """Raise InfeasibleError when the correcting line the run time makes at the look for
    the correction this job is planned with (``step.extra["correction"]``) is refused by
    the planner or the verifier the run time plans it with (no correction, or one within
    the tolerance: no move)."""
    import dataclasses

    from cellrunner.planning.align_correction import (
        correcting_goal,
        correcting_move,
        correction_text,
        within_tolerance,
    )
    from cellrunner.planning.group_timing import _time_and_verify
    from cellrunner.planning.step_plan import StepPlan
    from cellrunner.planning.step_planner import StepPlanner

    C = step.extra.get("correction")
    if C is None or within_tolerance(step, C):
        return
    world, q = planner.world, np.asarray(planner.q, float)
    T_goal = correcting_goal(
        step.extra["T_world_frame"], C, np.eye(4), world.kinematics.T_world_tcp(q)
    )
    try:  # as TaskPlan.replan plans a step planned nowhere: from here, nothing allowed
        motion = StepPlanner(world, q, planner.part).motion(
            StepPlan(correcting_move(step, T_goal)), allowances=()
        )
        _time_and_verify(world, motion, q)
    except InfeasibleError as exc:
        f = exc.failure
        raise InfeasibleError(
            dataclasses.replace(
                f,
                reason=f"the correcting line at the look for correction {correction_text(C)} "
                f"(a {np.linalg.norm(T_goal[:3, 3] - world.kinematics.T_world_tcp(q)[:3, 3]) * 1000:.1f}"
                f" mm straight move the run time makes before it looks again): {f.reason}",
                fix=f.fix
                or "fix: a smaller max_correction, or a look pose (standoff) "
                "farther from the singularity or fixture",
            )
        ) from exc
