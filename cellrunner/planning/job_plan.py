"""The plan of one job, the object that ``check``, ``run``, ``dry-run`` and ``serve`` share.

:func:`plan_job` expands the task's steps and its on_error steps once, plans them (or
takes the plan from the world's :class:`~cellrunner.planning.plan_store.PlanStore` when the
same inputs were planned before) and returns a frozen :class:`JobPlan`. Failures are
data on it (:class:`~cellrunner.model.failure.Failure`: which step, what kind, why,
what blocked it and the fix), never text to parse back.

The plan's key is made of digests taken when the files were loaded
(:attr:`LoadedCell.digest`, the task's ``source.digest``), the params, the start
configuration and the code that plans (the planning, model and step kinds' modules,
:data:`PLAN_SOURCES`): no file is read again per job.
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cellrunner import __version__
from cellrunner.errors import InternalError
from cellrunner.model.expand import expand_on_error
from cellrunner.model.failure import Failure
from cellrunner.model.geometry import Placed
from cellrunner.model.job_steps import job_steps
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue
from cellrunner.model.step import Step
from cellrunner.model.trajectory import ApprovedTrajectory, time_scaled
from cellrunner.planning.task_plan import StepPlan, TaskPlan, plan_task
from cellrunner.planning.world import CellWorld

if TYPE_CHECKING:
    pass


@dataclass(frozen=True, eq=False)
class JobPlan:
    """One job planned: its steps and on_error steps (expanded once), the approved
    trajectories and per-step rows (``task_plan``), and why it is refused (``failures``,
    empty when feasible). ``speed`` < 1 streams the approved motions slower, in time
    only (``run --speed``)."""

    key: str
    params: Mapping[str, ParamValue]
    steps: tuple[Step, ...]
    on_error_steps: tuple[Step, ...]
    task_plan: TaskPlan
    speed: float = 1.0
    #: the ``run --step`` flavour: every motion ends at rest
    joined: bool = True
    _paced: dict[str, PacedMotions] = field(default_factory=dict, repr=False)

    @property
    def ok(self) -> bool:
        return self.task_plan.ok

    @property
    def failures(self) -> tuple[Failure, ...]:
        return tuple(self.task_plan.failures)

    @property
    def warnings(self) -> list[str]:
        """What does not refuse the job but a user should know: each on_error step
        skipped from some states, on one line."""
        return [w.text() for w in self.task_plan.warnings]

    @property
    def errors(self) -> list[str]:
        """Each failure as one line naming its step."""
        return self.task_plan.errors

    @property
    def rows(self) -> list[StepPlan]:
        """The job's rows, then the on_error rows (verified from every state)."""
        return [*self.task_plan.rows, *self.task_plan.on_error]

    @property
    def cycle_time_s(self) -> float:
        """The planned cycle time at the approved pace (s)."""
        return self.task_plan.cycle_time_s

    @property
    def planned_cycle_time_s(self) -> float:
        """The cycle time as streamed, at ``speed`` (s)."""
        return self.task_plan.cycle_time_s / self.speed

    @property
    def run_steps(self) -> list[Step]:
        """What the job runner is handed: the steps, then the on_error steps (marked)."""
        return [*self.steps, *self.on_error_steps]

    @property
    def motions(self) -> TaskPlan | PacedMotions:
        """The approved motions as the engine streams them (at ``speed``)."""
        if self.speed == 1.0:
            return self.task_plan
        if "m" not in self._paced:
            self._paced["m"] = PacedMotions(self.task_plan, self.speed)
        return self._paced["m"]

    def paced(self, speed: float) -> JobPlan:
        """The same plan streamed at ``speed`` x the approved pace."""
        if not 0.0 < speed <= 1.0:
            raise InternalError(f"speed {speed:g} is outside (0, 1]")
        return replace(self, speed=speed, _paced={})


class PacedMotions:
    """A plan's motions streamed at ``speed`` x the approved pace: the very path ``check``
    approved, stretched in time only (see :func:`time_scaled`)."""

    def __init__(self, motions: TaskPlan, speed: float) -> None:
        if not 0.0 < speed <= 1.0:
            raise InternalError(f"speed {speed:g} is outside (0, 1]")
        self.motions, self.speed = motions, speed

    def nominal(self, step: Step) -> ApprovedTrajectory | None:
        approved = self.motions.nominal(step)
        return None if approved is None else time_scaled(approved, self.speed)

    def continues(self, step: Step) -> bool:
        return self.motions.continues(step)

    def replan(
        self, step: Step, q_now_rad: np.ndarray, carrying: bool, obstacles: Placed | None = None
    ) -> ApprovedTrajectory:
        return time_scaled(self.motions.replan(step, q_now_rad, carrying, obstacles), self.speed)

    def tcp_position_m(self, q_rad: np.ndarray, step: Step | None = None) -> np.ndarray:
        return self.motions.tcp_position_m(q_rad, step)

    def tcp_positions_m(self, q_rad: np.ndarray) -> np.ndarray:
        return self.motions.tcp_positions_m(q_rad)

    def tcp_pose(self, q_rad: np.ndarray) -> np.ndarray:
        return self.motions.tcp_pose(q_rad)

    def carried_during(self, step: Step) -> Placed | None:
        return self.motions.carried_during(step)


def plan_job(
    world: CellWorld,
    task: LoadedTask,
    params: Mapping[str, ParamValue],
    q_start_rad: np.ndarray,
    *,
    use_cache: bool = True,
    joined: bool = True,
    on_step: Callable[[Step], None] | None = None,
) -> JobPlan:
    """The plan of ``task`` with ``params`` from ``q_start_rad``: from the world's plan
    store when the same inputs were planned before, else planned (and stored when
    feasible). ``joined=False`` (run --step) ends every motion at rest. ``on_step(step)``
    is called per step as it is planned (all at once for a stored plan)."""
    values = dict(params)
    steps = job_steps(task, world.loaded.cell, values)  # shared with the twin, the runner
    on_error = (
        expand_on_error(task, world.loaded.cell, values, len(steps) + 1) if task.on_error else []
    )
    q_start = np.asarray(q_start_rad, float)
    key = plan_key(world, task, values, q_start, joined)

    def made(plan: TaskPlan) -> JobPlan:
        return JobPlan(key, values, tuple(steps), tuple(on_error), plan, joined=joined)

    if use_cache:
        from cellrunner.planning.plan_files import read_plan

        stored: TaskPlan | None = world.plans.get(
            key, lambda path: read_plan(path, world, steps, q_start, on_error)
        )
        if stored is not None:
            if on_step is not None:
                for step in steps:
                    on_step(step)
            return made(stored)
    plan = plan_task(world, steps, q_start, joined=joined, on_step=on_step)
    from cellrunner.planning.watch_view import watch_view_failures

    plan.failures.extend(watch_view_failures(world.loaded.cell))
    if on_error:
        from cellrunner.planning.on_error import verify_on_error

        plan.on_error, failures, plan.warnings = verify_on_error(plan, on_error)
        plan.failures.extend(failures)
    if use_cache:
        from cellrunner.planning.plan_files import write_plan

        world.plans.put(key, plan, (lambda path: write_plan(path, plan)) if plan.ok else None)
    return made(plan)


#: what a plan is made by, under the package: the modules and packages (with their data
#: files, e.g. the arms' link geometry) that planning a job reads. Each step kind plans
#: its own steps (``steps/``): a release that began to leave the pin in its hole as an
#: obstacle kept the old digest, and check approved the plan stored before, which swept
#: the open jaws through that pin (issue 33, s3000)
PLAN_SOURCES = ("__init__.py", "errors.py", "model", "planning", "steps")


def code_files() -> list[Path]:
    """The files of :data:`PLAN_SOURCES`, sorted (compiled caches left out)."""
    package = Path(__file__).resolve().parent.parent
    out: list[Path] = []
    for name in PLAN_SOURCES:
        path = package / name
        if path.is_dir():
            out.extend(p for p in path.rglob("*") if p.is_file() and "__pycache__" not in p.parts)
        else:
            out.append(path)
    return sorted(out)


@functools.lru_cache(maxsize=1)
def code_digest() -> bytes:
    """The code and data that plan a job (:func:`code_files`): a plan made by other code
    is another plan."""
    h = hashlib.sha256(__version__.encode())
    package = Path(__file__).resolve().parent.parent
    for path in code_files():
        h.update(path.relative_to(package).as_posix().encode())
        h.update(path.read_bytes())
    return h.digest()


def plan_key(
    world: CellWorld,
    task: LoadedTask,
    params: Mapping[str, ParamValue],
    q_start_rad: np.ndarray,
    joined: bool = True,
) -> str:
    """The key of a plan: the digests of the cell (meshes too) and task files taken when
    they were loaded, the params, the start and the planning code."""
    h = hashlib.sha256()
    h.update(code_digest())
    if not joined:
        h.update(b"every motion ends at rest")
    h.update(world.loaded.digest.encode())
    h.update(task.source.digest.encode())
    h.update(json.dumps(params, sort_keys=True).encode())
    h.update(np.round(np.asarray(q_start_rad, float), 6).tobytes())
    return h.hexdigest()[:32]
