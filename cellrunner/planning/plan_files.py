"""A task plan as a file of the plan store (:mod:`.plan_store`): ``.npz`` (arrays plus
JSON, no pickle) under ``var/plan-cache/`` of the project. What comes back from disk is
unsealed: each trajectory is verified again on first use (:meth:`TaskPlan.nominal`)
before it can be streamed. The store saves planning, never the safety check.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model.failure import Failure
from cellrunner.model.geometry import Placed
from cellrunner.model.step import Step
from cellrunner.model.trajectory import Trajectory
from cellrunner.planning.task_plan import StepPlan, TaskPlan, VerifyInputs

if TYPE_CHECKING:
    from cellrunner.planning.world import CellWorld


def write_plan(path: Path, plan: TaskPlan) -> None:
    """Write ``plan`` to ``path`` (nothing when the project is read-only)."""
    arrays: dict[str, np.ndarray] = {}
    meta = []
    for i, row in enumerate(plan.rows):
        entry = {
            "status": row.status,
            "message": row.message,
            "duration_s": row.duration_s,
            "part": row.carrying.name if row.carrying is not None else None,
            "allow": [[a.fixture, a.robot_part, a.min_clearance_m] for a in row.allowances],
            "tool": list(row.world.tool_key)
            if row.world is not None and row.world.tool_key
            else None,
        }
        # the parts set down before this step: obstacles its plan was made around
        placed = row.world.placed if row.world is not None else ()
        entry["placed"] = [[p.name, p.shape_name] for p in _placed_parts(placed)]
        for k, p in enumerate(placed):
            arrays[f"placed{i}_{k}"] = p.T_parent_shape
        if row.carrying is not None:
            arrays[f"part{i}"] = row.carrying.T_parent_shape
        if row.q_end_rad is not None:
            arrays[f"qend{i}"] = np.asarray(row.q_end_rad)
        if row.trajectory is not None:
            inputs = row.verify_inputs
            assert inputs is not None  # a planned trajectory keeps what verified it
            arrays[f"q{i}"] = row.trajectory.q_rad
            arrays[f"prev{i}"] = np.asarray(inputs["previous_q_rad"])
            if inputs["line_m"] is not None:
                arrays[f"line{i}"] = np.asarray(inputs["line_m"])
            entry.update(
                previous_moving=inputs["previous_moving"], ends_at_rest=inputs["ends_at_rest"]
            )
        meta.append(entry)
    # every array in one float64 blob, indexed in the JSON: reading an .npz member costs
    # ~0.4 ms (zip entry, header parse), and a plan has ~30 arrays
    index, offset = {}, 0
    for name, array in arrays.items():
        index[name] = [offset, list(np.shape(array))]
        offset += int(np.size(array))
    blob = (
        np.concatenate([np.asarray(a, float).ravel() for a in arrays.values()])
        if arrays
        else np.zeros(0)
    )
    on_error = [[r.status, r.message] for r in plan.on_error]
    failures = [f.to_json() for f in plan.failures]
    warnings = [f.to_json() for f in plan.warnings]
    header = json.dumps(
        {
            "rows": meta,
            "arrays": index,
            "on_error": on_error,
            "failures": failures,
            "warnings": warnings,
        }
    ).encode()
    buffer = io.BytesIO()
    np.savez(buffer, meta=np.frombuffer(header, dtype=np.uint8), blob=blob)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(buffer.getvalue())
        tmp.replace(path)
    except OSError:
        pass  # a read-only project: the cache is an optimisation only


@dataclass(frozen=True)
class _PlacedPart:
    """A placed part as the plan file names it: its fixture name and the cell's part."""

    name: str
    shape_name: str


def _placed_parts(placed: tuple[Placed, ...]) -> list[_PlacedPart]:
    """``placed:NAME@STEP`` -> (that name, NAME)."""
    from cellrunner.model.body import Body

    return [_PlacedPart(p.name, Body.fixture(p.name).name.rsplit("@", 1)[0]) for p in placed]


def read_plan(
    path: Path,
    world: CellWorld,
    steps: list[Step],
    q_start_rad: np.ndarray,
    cleanup: list[Step],
) -> TaskPlan | None:
    """The stored plan with its trajectories unsealed: :meth:`TaskPlan.nominal` verifies
    each one again before it can be streamed."""
    from cellrunner.planning.collision import ContactAllowance

    try:
        with np.load(path, allow_pickle=False) as stored:
            header = json.loads(bytes(stored["meta"]).decode())
            blob = stored["blob"]
        meta = header["rows"]
        verified = header["on_error"]
        # copies: a view would keep the whole blob alive beside the trajectories' own copies
        # for as long as the plan is kept in memory
        data = {
            name: blob[offset : offset + math.prod(shape)].reshape(shape).copy()
            for name, (offset, shape) in header["arrays"].items()
        }
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if len(meta) != len(steps) or len(verified) != len(cleanup):
        return None
    rows = []
    rate = world.spec.rate_hz
    try:
        for i, (step, entry) in enumerate(zip(steps, meta, strict=True)):
            row = StepPlan(step, entry["status"], entry["message"], entry["duration_s"])
            if entry["part"] is not None:
                shape = next(p for p in world.loaded.cell.parts if p.name == entry["part"])
                row.carrying = Placed(
                    shape.name, shape.to_shape(world.loaded.resolve), data[f"part{i}"]
                )
            row.allowances = tuple(ContactAllowance(*a) for a in entry["allow"])
            row.world = world.with_tool(*entry["tool"]) if entry.get("tool") else world
            placed = []
            for k, (name, part_name) in enumerate(entry["placed"]):
                spec = next(p for p in world.loaded.cell.parts if p.name == part_name)
                placed.append(
                    Placed(name, spec.to_shape(world.loaded.resolve), data[f"placed{i}_{k}"])
                )
            row.world = row.world.with_placed(*placed)
            if f"qend{i}" in data:
                row.q_end_rad = data[f"qend{i}"]
            if f"q{i}" in data:
                q = data[f"q{i}"]
                row.trajectory = Trajectory(rate, np.arange(len(q)) / rate, q)
                row.verify_inputs = VerifyInputs(
                    previous_q_rad=data[f"prev{i}"],
                    previous_moving=entry["previous_moving"],
                    ends_at_rest=entry["ends_at_rest"],
                    line_m=tuple(data[f"line{i}"]) if f"line{i}" in data else None,
                )
            rows.append(row)
    except (KeyError, StopIteration, ValueError):
        return None
    on_error = [
        StepPlan(s, status, message) for s, (status, message) in zip(cleanup, verified, strict=True)
    ]
    try:
        failures = [Failure.from_json(f) for f in header.get("failures", [])]
        warnings = [Failure.from_json(f) for f in header.get("warnings", [])]
    except (KeyError, TypeError, ValueError):  # a file written before failures were data
        return None
    return TaskPlan(
        world,
        steps,
        rows,
        np.asarray(q_start_rad, float),
        failures=failures,
        on_error=on_error,
        warnings=warnings,
    )
