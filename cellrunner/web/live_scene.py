"""What the live 3D view draws, as JSON-ready data built from the cell model.

* :func:`scene_of` - once per page: the arm's links (the convex parts of the planning
  model, :mod:`cellrunner.model.arm_geometry`, each in its link's frame), the tool's shapes
  (flange frame), the fixtures (world frame), the watched zone.
* :class:`ArmPoses` - the world pose of every link and of the flange and TCP at a joint
  configuration, by the arm's one kinematics
  (:class:`~cellrunner.planning.kinematics.ArmKinematics`, pinocchio forward kinematics on
  data of its own, so it may run on any one thread beside the planner's).
* :func:`job_of` - once per job: its planned TCP path, step by step, and the shapes of the
  parts it carries.

Poses are 4x4 homogeneous matrices sent row-major as 16 numbers (``T_world_link``: the
link's frame in the world), lengths in m, rounded to 0.1 mm.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from cellrunner.execution.planner import PlannedJob
from cellrunner.model.arm_geometry import LINK_NAMES, arm_geometry
from cellrunner.model.expand import ON_ERROR
from cellrunner.model.geometry import Box, Cylinder, Mesh, Placed, Shape, Sphere, Voxels
from cellrunner.model.watch import Watch
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.world import CellWorld

#: decimals of every length sent (0.1 mm)
DECIMALS = 4
#: the most TCP points a job's path is drawn with (every motion keeps its two ends)
PATH_POINTS_MAX = 4000


def matrix_json(T: np.ndarray) -> list[float]:
    """A 4x4 pose as 16 numbers, row-major."""
    return [round(float(v), 6) for v in np.asarray(T, dtype=float).reshape(16)]


def _lengths(values: np.ndarray) -> list[float]:
    return [round(float(v), DECIMALS) for v in np.asarray(values, dtype=float).reshape(-1)]


def shape_json(shape: Shape) -> dict[str, Any]:
    """One shape in its own frame: box (full edge lengths), cylinder (along its Z,
    centred), sphere, mesh (vertices, triangles) or voxels (cubes of edge ``voxel``)."""
    if isinstance(shape, Box):
        return {"kind": "box", "size": _lengths(np.array(shape.size_m))}
    if isinstance(shape, Cylinder):
        return {"kind": "cylinder", "radius": shape.radius_m, "length": shape.length_m}
    if isinstance(shape, Sphere):
        return {"kind": "sphere", "radius": shape.radius_m}
    if isinstance(shape, Mesh):
        from cellrunner.planning.stl import read_stl

        vertices, faces = read_stl(shape.path)
        return {
            "kind": "mesh",
            "vertices": _lengths(vertices * shape.scale),
            "faces": [int(i) for i in faces.reshape(-1)],
        }
    if isinstance(shape, Voxels):
        return {"kind": "voxels", "voxel": shape.voxel_m, "centres": _lengths(shape.centres_m)}
    raise TypeError(f"no drawing of shape {type(shape).__name__}")


def placed_json(placed: Iterable[Placed]) -> list[dict[str, Any]]:
    return [
        {"name": p.name, "T": matrix_json(p.T_parent_shape), **shape_json(p.shape)} for p in placed
    ]


def scene_of(world: CellWorld, watch: Watch | None = None) -> dict[str, Any]:
    """The parts of the cell that do not change during a job (module docstring)."""
    cell = world.loaded.cell
    geometry = arm_geometry(world.spec.name)
    links: list[dict[str, Any]] = [{"name": name, "parts": []} for name in LINK_NAMES]
    for part in geometry.parts:
        links[part.body]["parts"].append(
            {
                "kind": "mesh",
                "vertices": _lengths(part.vertices_m),
                "faces": [int(i) for i in part.faces.reshape(-1)],
            }
        )
    zone = None
    if watch is not None:
        size = watch.zone.box.size
        zone = {
            "T": matrix_json(watch.zone.pose.matrix()),
            "size": [size[0], size[1], size[2]],
            "voxel": watch.voxel,
        }
    return {
        "cell": cell.cell,
        "robot": world.spec.name,
        "links": links,
        "tool": placed_json(world.tool),
        "fixtures": placed_json(world.fixtures),
        "zone": zone,
        "home_deg": [float(v) for v in np.degrees(world.q_home_rad)],
    }


class ArmPoses:
    """World poses of the arm's links at a configuration (module docstring). Use one
    instance from one thread at a time."""

    def __init__(self, kinematics: ArmKinematics) -> None:
        import pinocchio as pin

        self._pin = pin
        self.kinematics = kinematics
        self.model = kinematics.model
        self.data = kinematics.model.createData()  # not the planner's: no sharing

    def links(self, q_rad: np.ndarray) -> list[np.ndarray]:
        """``T_world_link`` of the base and of the links moved by joints 1-6 (7 poses);
        then the flange and the TCP."""
        pin = self._pin
        q = np.asarray(q_rad, dtype=float)
        pin.framesForwardKinematics(self.model, self.data, q)
        poses = [self.kinematics.T_world_base.copy()]
        poses += [np.asarray(self.data.oMi[j].homogeneous) for j in range(1, 7)]
        poses.append(np.asarray(self.data.oMf[self.kinematics.flange_frame_id].homogeneous))
        poses.append(np.asarray(self.data.oMf[self.kinematics.tcp_frame_id].homogeneous))
        return poses


def tool_key(world: CellWorld) -> str:
    """A name for the tool a world mounts: "" for the cell file's, else the tool's name
    (``-`` for the bare flange), with the TCP it carries when that is another tool's."""
    if world.tool_key is None:
        return ""
    tool, tcp_of = world.tool_key
    return (tool or "-") + (f"@{tcp_of}" if tcp_of and tcp_of != tool else "")


def world_at(plan: PlannedJob | None, step_index: int) -> CellWorld | None:
    """The world (the mounted tool) step ``step_index`` (1-based) runs in, as the plan
    has it: that of the last step up to it that names one; None: the plan's first."""
    rows = getattr(plan, "rows", None) or []
    found = None
    for row in rows:
        if row.step.index > step_index or row.step.macro_kind == ON_ERROR.kind:
            break
        if row.world is not None:
            found = row.world
    return found


def _holdings(plan: PlannedJob) -> list[tuple[int, Placed | None]]:
    """(step index, the part held once it ended) of each step that is not a motion (a
    grip takes a part, a release lets it go), in run order, the on_error steps left out."""
    rows = getattr(plan, "rows", None) or []
    return [
        (row.step.index, row.carrying)
        for row in rows
        if row.step.macro_kind != ON_ERROR.kind and not row.step.is_motion
    ]


def job_of(job_id: str, plan: PlannedJob, world: CellWorld) -> dict[str, Any]:
    """A job's planned TCP path (one polyline per approved motion, in run order, the
    on_error steps left out, each with the tool mounted then), the shapes of the parts it
    carries (TCP frame) and of the tools it mounts (flange frame, by :func:`tool_key`).
    ``world``: the cell's, for steps the plan names no world for."""
    motions = plan.motions
    segments: list[tuple[int, str, np.ndarray, CellWorld]] = []
    tools: dict[str, list[dict[str, Any]]] = {}
    for step in plan.run_steps:
        if step.macro_kind == ON_ERROR.kind:
            continue
        mounted = world_at(plan, step.index) or world
        key = tool_key(mounted)
        if key not in tools:
            tools[key] = placed_json(mounted.tool)
        approved = motions.nominal(step)
        if approved is not None:
            segments.append((step.index, step.name, approved.trajectory.q_rad, mounted))
    carried: dict[str, dict[str, Any]] = {}
    for _, part in _holdings(plan):
        if part is not None and part.name not in carried:
            carried[part.name] = {"T": matrix_json(part.T_parent_shape), **shape_json(part.shape)}
    total = sum(len(q) for _, _, q, _ in segments)
    stride = max(1, -(-total // PATH_POINTS_MAX))
    path = []
    for index, name, q, mounted in segments:
        keep = np.unique(np.r_[np.arange(0, len(q), stride), len(q) - 1])
        points = mounted.kinematics.p_world_tcp_many(q[keep])
        path.append({"step": index, "name": name, "points": _lengths(points)})
    return {"job_id": job_id, "path": path, "parts": carried, "tools": tools}


def carried_part(plan: PlannedJob | None, step_index: int) -> Placed | None:
    """The part the plan has the gripper hold while step ``step_index`` (1-based) runs:
    what the last grip or release before it left in the gripper (a grip's part shows
    once the grip ended; a release's stays until it ended). None when none or unknown."""
    if plan is None or step_index <= 0:
        return None
    held: Placed | None = None
    for index, part in _holdings(plan):
        if index >= step_index:
            break
        held = part
    return held
