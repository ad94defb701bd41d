"""``check``'s sweep over the values a job may be started with: every slot of every
pattern param and the centre and corners of every pose param's box, each planned as a
job (:func:`~cellrunner.planning.job_plan.plan_job`).

Planning is single-threaded Python: the slots to plan afresh are shared with a forked
child process when a second core is free. The child inherits the loaded cell and what
the requested job's plan left in the world's memos (the moves and on_error states slots
share) and sends back only the failures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from cellrunner.model.expand import box_params, float_params, frame_params, pattern_params
from cellrunner.model.failure import Failure
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue
from cellrunner.model.step import Step

if TYPE_CHECKING:
    from cellrunner.planning.job_plan import JobPlan
    from cellrunner.planning.world import CellWorld

#: how long the parent waits for the child's slots before planning them itself (s)
CHILD_TIMEOUT_S = 120.0


class SweepProgress(Protocol):
    """What a sweep tells a progress bar: a plan starts (``plan(label)`` returns its
    ``on_step``), or ``n`` plans finished elsewhere (``skip(n)``, in a forked child)."""

    def plan(self, label: str) -> Callable[[Step], None] | None: ...

    def skip(self, n_plans: int) -> None: ...

    def sized(self, steps_per_plan: int) -> None: ...


class _Silent:
    def plan(self, label: str) -> Callable[[Step], None] | None:
        return None

    def skip(self, n_plans: int) -> None:
        return None

    def sized(self, steps_per_plan: int) -> None:
        return None


@dataclass(frozen=True)
class SlotFailure:
    """Another value ``value`` of param ``param`` cannot be run: ``failure`` says which
    step, what kind of refusal and what blocked it."""

    param: str
    value: ParamValue
    failure: Failure


@dataclass(frozen=True)
class Sweep:
    """The requested job's plan and what the other values of its params gave."""

    plan: JobPlan
    #: param -> every value checked (slots, or a pose box's centre and corners)
    checked: dict[str, list[ParamValue]]
    failures: list[SlotFailure]

    @property
    def ok(self) -> bool:
        return self.plan.ok and not self.failures


def checked_values(task: LoadedTask) -> dict[str, list[ParamValue]]:
    """Param -> every value the sweep checks: each slot of each pattern, the centre and
    corners of each pose param's box and each align's correction box, the ends and
    centre of each float param's range that may change a motion, and every choice of each
    frame param."""
    checked: dict[str, list[ParamValue]] = {n: list(v) for n, v in pattern_params(task).items()}
    checked.update({n: list(v) for n, v in box_params(task).items()})
    checked.update({n: list(v) for n, v in float_params(task).items()})
    checked.update({n: list(v) for n, v in frame_params(task).items()})
    return checked


def other_values(task: LoadedTask, params: dict[str, ParamValue]) -> list[dict[str, ParamValue]]:
    """The params of every other job the sweep plans (:func:`checked_values`), the rest
    as given."""
    checked = checked_values(task)
    return [
        {**params, name: value}
        for name, values in checked.items()
        for value in values
        if value != params.get(name)
    ]


def sweep(
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    *,
    use_cache: bool = True,
    progress: SweepProgress | None = None,
) -> Sweep:
    """Plan ``task`` with ``params`` from home, then every other value of its pattern and
    pose params (:func:`other_values`)."""
    from cellrunner.planning.job_plan import plan_job

    progress = progress or _Silent()
    plan = plan_job(
        world,
        task,
        params,
        world.q_home_rad,
        use_cache=use_cache,
        on_step=progress.plan(_params_text(params)),
    )
    progress.sized(len(plan.steps))
    others = other_values(task, params)
    stored = [p for p in others if use_cache and world.plans.has(_key(world, task, p))]
    fresh = [p for p in others if p not in stored]
    found_all = [
        *_plan_split(world, task, fresh, use_cache, progress),
        *_slot_errors(world, task, stored, use_cache, progress),
    ]
    failures = [
        SlotFailure(k, given[k], e)
        for given, found in found_all
        for k in given
        if given[k] != params.get(k)
        for e in found
    ]
    return Sweep(plan, checked_values(task), failures)


def _key(world: CellWorld, task: LoadedTask, params: dict[str, ParamValue]) -> str:
    from cellrunner.planning.job_plan import plan_key

    return plan_key(world, task, params, world.q_home_rad)


def _params_text(params: dict[str, ParamValue]) -> str:
    return ", ".join(f"{k}={v}" for k, v in params.items())


def _slot_errors(
    world: CellWorld,
    task: LoadedTask,
    slots: list[dict[str, ParamValue]],
    use_cache: bool,
    progress: SweepProgress,
) -> list[tuple[dict[str, ParamValue], tuple[Failure, ...]]]:
    from cellrunner.planning.job_plan import plan_job

    return [
        (
            p,
            plan_job(
                world,
                task,
                p,
                world.q_home_rad,
                use_cache=use_cache,
                on_step=progress.plan(_params_text(p)),
            ).failures,
        )
        for p in slots
    ]


def _plan_split(
    world: CellWorld,
    task: LoadedTask,
    slots: list[dict[str, ParamValue]],
    use_cache: bool,
    progress: SweepProgress,
) -> list[tuple[dict[str, ParamValue], tuple[Failure, ...]]]:
    """``_slot_errors`` of every slot, half of them in a forked child process when this
    process may run on more than one core. If the child fails, the parent plans its half
    too."""
    import multiprocessing
    import os

    cores = (
        len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    )
    if cores < 2 or len(slots) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return _slot_errors(world, task, slots, use_cache, progress)
    theirs, mine = slots[: len(slots) // 2], slots[len(slots) // 2 :]
    context = multiprocessing.get_context("fork")
    reader, writer = context.Pipe(duplex=False)

    def child() -> None:
        writer.send([found for _, found in _slot_errors(world, task, theirs, use_cache, _Silent())])

    process = context.Process(target=child, daemon=True)
    process.start()
    writer.close()
    results = _slot_errors(world, task, mine, use_cache, progress)
    try:
        found = reader.recv() if reader.poll(CHILD_TIMEOUT_S) else None
    except (EOFError, OSError):
        found = None
    process.join(timeout=1.0)
    if process.is_alive():
        process.kill()
        process.join()
    reader.close()
    if found is None or len(found) != len(theirs):
        return [*_slot_errors(world, task, theirs, use_cache, progress), *results]
    progress.skip(len(theirs))
    return [*zip(theirs, found, strict=True), *results]
