"""The planner the cell uses for a job: the task plan (from the plan cache when the same
job was planned before, its trajectories verified again on the planning thread), refused
as a whole when any step is infeasible."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.errors import InfeasibleError
from cellrunner.execution.context import Motions
from cellrunner.model.expand import Step
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue

if TYPE_CHECKING:
    from cellrunner.planning.task_plan import TaskPlan
    from cellrunner.planning.world import CellWorld


class PlannedJob(Protocol):
    """What the cell runs of a job's plan: the one plan object,
    :class:`cellrunner.planning.job_plan.JobPlan`, is one."""

    @property
    def run_steps(self) -> list[Step]:
        """The steps in order, then the task's on_error steps (marked)."""

    @property
    def motions(self) -> Motions:
        """The approved trajectories, as streamed."""

    @property
    def planned_cycle_time_s(self) -> float:
        """The cycle time as streamed (s)."""


#: plans a job: (task, params, where the arm stands, rad) -> its plan, or raises
Planner = Callable[[LoadedTask, dict[str, ParamValue], np.ndarray], PlannedJob]

#: a start this close to home (max over joints, rad) is planned from home, so that jobs
#: that begin at home reuse the cached plan
HOME_SNAP_RAD = 1e-3


def job_planner(
    world: CellWorld, *, use_cache: bool = True, speed: float = 1.0, joined: bool = True
) -> Planner:
    """``speed`` < 1 streams the approved motions slower, in time only (run --speed);
    ``joined=False`` plans every motion to end at rest (run --step)."""
    from cellrunner.planning.job_plan import plan_job

    def plan(task: LoadedTask, params: dict[str, ParamValue], q_now_rad: np.ndarray) -> PlannedJob:
        q = np.asarray(q_now_rad, float)
        if np.max(np.abs(q - world.q_home_rad)) < HOME_SNAP_RAD:
            q = world.q_home_rad
        job = plan_job(world, task, params, q, use_cache=use_cache, joined=joined)
        if not job.ok:
            raise InfeasibleError(job.failures[0], job.failures[1:])
        _verify_ahead(job.task_plan)
        # the task's on_error steps ride along (run_steps), marked, for the runner to keep
        return job.paced(speed) if speed != 1.0 else job

    return plan


def _verify_ahead(task_plan: TaskPlan) -> None:
    """Verify a cached plan's trajectories here, on the planning thread, so that no control
    tick waits on a collision check. A trajectory that fails stays unverified: streaming
    it verifies it again and fails that step, as without this."""
    for step in task_plan.steps:
        if step.is_motion:
            try:
                task_plan.nominal(step)
            except InfeasibleError:
                return


def warm_up(world: CellWorld) -> None:
    """Do now what the first job's planning would do lazily: import the planning stack
    (pinocchio, coal, OMPL, TOPP-RA) and build the cell's kinematics, collision model and
    limits, so the first job is acknowledged as fast as any other (``serve`` calls this
    before it raises READY)."""
    import importlib

    for module in (
        "task_plan",
        "timing",
        "verify",
        "joint_path",
        "cartesian",
        "collision",
        "job_plan",
        "plan_files",
    ):
        importlib.import_module(f"cellrunner.planning.{module}")
    # joint_path imports OMPL only when it searches (check and validate never load it), so
    # without this the first job that needs a search loaded it (~7 MiB) in the middle of a
    # serve: the soak's memory after 50 jobs depended on when a fault first left the arm
    # away from a cached start
    for module in ("ompl.base", "ompl.geometric", "ompl.util"):
        importlib.import_module(module)
    world.kinematics.T_world_tcp(world.q_home_rad)
    _ = world.collision, world.limits
