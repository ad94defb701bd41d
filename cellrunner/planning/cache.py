"""A plan cache keyed by everything a plan depends on: the cell, task and mesh files'
bytes, the params, the start configuration and the planning code itself. A repeated job
reuses its approved trajectories without planning; any change to the files misses.

Entries live in memory (for ``serve``) and on disk as ``.npz`` (arrays plus JSON, no
pickle) under ``var/plan-cache/`` of the project. What comes back from disk is unsealed:
each trajectory is verified again on first use (:meth:`TaskPlan.nominal`) before it can be
streamed. The cache saves planning, never the safety check.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from cellrunner import __version__
from cellrunner.model.expand import expand
from cellrunner.model.geometry import Mesh, Placed
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue
from cellrunner.model.step import Step
from cellrunner.model.trajectory import Trajectory
from cellrunner.planning.task_plan import StepPlan, TaskPlan, VerifyInputs, plan_task
from cellrunner.planning.world import CellWorld

#: plans kept in memory (serve), least recently used first. A job that starts where a fault
#: left the arm has a plan of its own that is rarely used again; with a bound of 64 those
#: (~0.5 MB each) grew serve's memory by 10 % over 250 soak jobs (bench_plc). So a plan is
#: kept from its second use on (the first repeat reads it from disk): keys asked for once
#: are remembered, oldest out, and one-off plans never take the place of the ones in use
_MEMORY: dict[str, TaskPlan] = {}
_MEMORY_MAX = 16
_ASKED_ONCE: dict[str, None] = {}
_ASKED_ONCE_MAX = 1024


@functools.lru_cache(maxsize=1)
def _code_digest() -> bytes:
    """The planning and model sources: a plan made by other code is another plan."""
    h = hashlib.sha256(__version__.encode())
    package = Path(__file__).resolve().parent.parent
    for path in sorted([*package.glob("planning/*.py"), *package.glob("model/*.py")]):
        h.update(path.read_bytes())
    return h.digest()


def plan_key(
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    q_start_rad: np.ndarray,
    joined: bool = True,
) -> str:
    h = hashlib.sha256()
    h.update(_code_digest())
    if not joined:
        h.update(b"every motion ends at rest")
    for path in [world.loaded.path, task.path, *sorted(m.path for m in _meshes(world))]:
        h.update(str(path).encode())
        h.update(Path(path).read_bytes())
    h.update(json.dumps(params, sort_keys=True).encode())
    h.update(np.round(np.asarray(q_start_rad, float), 6).tobytes())
    return h.hexdigest()[:32]


def _meshes(world: CellWorld) -> list[Mesh]:
    return [p.shape for p in [*world.fixtures, *world.tool] if isinstance(p.shape, Mesh)]


def cache_dir(world: CellWorld) -> Path:
    return world.loaded.root / "var" / "plan-cache"


def plan_cached(
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    q_start_rad: np.ndarray,
    *,
    use_cache: bool = True,
    joined: bool = True,
    on_step: Callable[[Step], None] | None = None,
) -> TaskPlan:
    """The plan of ``task`` with ``params`` from ``q_start_rad``: from the cache when the
    same inputs were planned before, else planned (and stored when feasible).
    ``on_step(step)``: called per step as it is planned (all at once for a cached plan)."""
    steps = expand(task, world.loaded.cell, params)
    if not use_cache:
        fresh = plan_task(world, steps, q_start_rad, joined=joined, on_step=on_step)
        return _verify_on_error(fresh, task, params)
    key = plan_key(world, task, params, q_start_rad, joined)
    plan = _MEMORY.get(key)
    if plan is not None and plan.world is world:
        _MEMORY[key] = _MEMORY.pop(key)  # the most recently used goes last
        if on_step is not None:
            for step in steps:
                on_step(step)
        return plan
    path = cache_dir(world) / f"{key}.npz"
    cleanup = _on_error_steps(task, world, params, len(steps))
    plan = _load(path, world, steps, q_start_rad, cleanup) if path.is_file() else None
    if plan is not None and on_step is not None:
        for step in steps:
            on_step(step)
    if plan is None:
        plan = _verify_on_error(
            plan_task(world, steps, q_start_rad, joined=joined, on_step=on_step), task, params
        )
        if plan.ok:
            _store(path, plan)
    _keep(key, plan)
    return plan


def _keep(key: str, plan: TaskPlan) -> None:
    """Keep ``plan`` in memory if ``key`` was asked for before (see ``_MEMORY``)."""
    if key not in _ASKED_ONCE:
        while len(_ASKED_ONCE) >= _ASKED_ONCE_MAX:
            _ASKED_ONCE.pop(next(iter(_ASKED_ONCE)))
        _ASKED_ONCE[key] = None
        return
    del _ASKED_ONCE[key]
    _MEMORY.pop(key, None)
    while len(_MEMORY) >= _MEMORY_MAX:
        _MEMORY.pop(next(iter(_MEMORY)))  # the least recently used
    _MEMORY[key] = plan


def _on_error_steps(
    task: LoadedTask, world: CellWorld, params: dict[str, ParamValue], n_steps: int
) -> list[Step]:
    from cellrunner.model.expand import expand_on_error

    return expand_on_error(task, world.loaded.cell, params, n_steps + 1) if task.on_error else []


def _verify_on_error(plan: TaskPlan, task: LoadedTask, params: dict[str, ParamValue]) -> TaskPlan:
    """The task's on_error steps verified from every state the plan can fail in; an
    infeasible one makes the plan infeasible (an error naming the step)."""
    from cellrunner.planning.on_error import on_error_errors, verify_on_error

    cleanup = _on_error_steps(task, plan.world, params, len(plan.steps))
    if cleanup:
        plan.on_error = verify_on_error(plan, cleanup)
        plan.errors.extend(on_error_errors(plan.on_error))
    return plan


def _store(path: Path, plan: TaskPlan) -> None:
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
    header = json.dumps({"rows": meta, "arrays": index, "on_error": on_error}).encode()
    buffer = io.BytesIO()
    np.savez(buffer, meta=np.frombuffer(header, dtype=np.uint8), blob=blob)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(buffer.getvalue())
        tmp.replace(path)
    except OSError:
        pass  # a read-only project: the cache is an optimisation only


def _load(
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
    return TaskPlan(world, steps, rows, np.asarray(q_start_rad, float), on_error=on_error)
