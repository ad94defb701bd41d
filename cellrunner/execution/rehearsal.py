"""A dry-run's rehearsal: the real cell controller and job runner driving the MuJoCo twin
through one job or several in a row (the parts staying where each job put them), with
faults made to happen physically when their moment comes.

:func:`start_rehearsal` assembles the cell on a twin backend (built by
:func:`~cellrunner.backends.factory.make_backend`); :meth:`Rehearsal.rehearse` runs one
job to its end and gives a :class:`RehearsedJob`: its :class:`ResultCode` (typed, turned
into a number only in the JSON and the exit status) and its JSON payload. The CLI parses,
calls and prints; the report is written from what the rehearsal recorded.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from rich.markup import escape

from cellrunner.errors import CellrunnerError
from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.journal import Journal
from cellrunner.model.codes import ResultCode
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.step import StepKind

if TYPE_CHECKING:
    from cellrunner.execution.assembly import AssembledCell
    from cellrunner.execution.cell import CellController
    from cellrunner.execution.loop import ControlLoop
    from cellrunner.model.load import LoadedCell, LoadedTask
    from cellrunner.model.step import Step
    from cellrunner.perception.known import KnownScene

#: e-stop faults are released by the "operator" this long after they struck (sim s)
PLC_OUTAGE_S = 2.0
#: an injected intrusion drops at least this far from the arm as it stands (m)
INTRUSION_MARGIN_M = 0.02
#: with no room for it yet, an intrusion is tried again this much later (s)
INTRUSION_RETRY_S = 0.05


class Fault(Protocol):
    """A fault to make happen at a step (``--inject FAULT@STEP``)."""

    @property
    def fault(self) -> str: ...
    @property
    def step_index(self) -> int: ...
    @property
    def spec(self) -> str: ...
    def delay_within_s(self, step_s: float | None) -> float: ...


class Recording(Protocol):
    """Where the rehearsal's samples and moments go for the report."""

    @property
    def next_due_s(self) -> float: ...
    def mark(self, time_s: float, step: Step) -> None: ...
    def moment(self, name: str, sim_world: Any) -> None: ...
    def due(self, time_s: float) -> bool: ...
    def sample(self, *args: Any, **kwargs: Any) -> None: ...


@dataclass(frozen=True)
class RehearsedJob:
    """One job rehearsed: its result code and its JSON payload (the wall times
    ``wall_plan_s``/``wall_run_s`` in it until the output takes them out)."""

    code: ResultCode
    payload: dict[str, Any]

    @property
    def ok(self) -> bool:
        return self.code is ResultCode.OK


@dataclass
class Rehearsal:
    """One twin and its cell controller, rehearsing jobs one after the other (the parts
    staying where each job put them). ``recorder`` None: no report."""

    assembled: AssembledCell
    backend: Any
    out: Any
    faults: Sequence[Fault] = ()
    recorder: Recording | None = None
    #: the ``steps`` rows of the JSON from the job's records and its steps
    rows_of: Callable[[Any, list[Step]], list[dict[str, Any]]] = lambda job, steps: []
    pending: list[tuple[Fault, float]] = field(default_factory=list)

    @property
    def controller(self) -> CellController:
        return self.assembled.controller

    @property
    def loop(self) -> ControlLoop:
        return self.assembled.loop

    def on_step_start(self, step: Step, attempt: int) -> None:
        """Each step as it starts: the report's mark; its faults are due after the delay
        each takes within the step's motion."""
        now = self.backend.read_state().time_s
        if self.recorder is not None:
            self.recorder.mark(now, step)
        for inj in self.faults:
            if (
                inj.step_index == step.index
                and attempt == 1
                and all(p[0] is not inj for p in self.pending)
            ):
                moves_s = self.controller.planned_motion_s(step)
                self.pending.append((inj, now + inj.delay_within_s(moves_s)))

    def rehearse_all(self, jobs: Sequence[dict[str, Any]], task: LoadedTask) -> list[RehearsedJob]:
        """Each job in turn, a part fed before each where the twin feeds parts."""
        from cellrunner.model.job_steps import job_steps

        done = []
        for params in jobs:
            if self.backend.world is not None and self.backend.world.feeder is not None:
                self.backend.feed_parts()  # the conveyor brings the next part (sim: feed)
            steps = job_steps(task, self.controller.cell.cell, params)
            job = self.rehearse(params, steps)
            job.payload["injected"] = [i.spec for i in self.faults]
            done.append(job)
        return done

    def _until_ready(self) -> None:
        """After a job: Complete becomes Idle by itself; a stopped cell is reset (the
        operator's Reset between two rehearsed jobs)."""
        rate = int(self.backend.description.rate_hz)
        if ready_within(self.loop, self.controller, rate):
            return
        self.controller.command("reset")
        if not ready_within(self.loop, self.controller, 10 * rate):
            state = self.controller.status().state_name
            raise CellrunnerError(f"the cell did not come back to Idle after a job (state {state})")

    def rehearse(self, params: dict[str, Any], steps: list[Step]) -> RehearsedJob:
        """Run one job with ``params`` to its end."""
        controller, loop, backend = self.controller, self.loop, self.backend
        cell = controller.cell
        self._until_ready()
        t0 = time.perf_counter()
        with self.out.status("planning", spinner="dots") as status:
            ticket = controller.start_job(1, params, "dry-run", "cli")
            if not ticket.accepted:
                raise CellrunnerError(f"dry-run job refused: {ticket.message}")
            loop.step(1)  # the control thread starts planning
            controller.wait_for_plan(timeout_s=3600.0)
            wall_plan_s = time.perf_counter() - t0
            t_run = time.perf_counter()
            sim_t0 = backend.read_state().time_s
            observer = FaultsAndProgress(
                backend,
                self.pending,
                self.recorder,
                status,
                steps,
                self.assembled.world,
                {**cell.cell.io.outputs, **cell.cell.io.inputs},
            )
            loop.add_observer(observer)
            loop.step(1)  # the plan is picked up: the job runs (or ended with 103)
            view = controller.job_view(records=False) or controller.last_job
            planned_s = (view.planned_cycle_time_s or 0.0) if view is not None else 0.0
            loop.run_job(max_s=planned_s * 4 + 60)
            loop.observers.remove(observer)
            wall_run_s = time.perf_counter() - t_run
        job = controller.last_job
        result = controller.status().last_result
        assert result is not None and job is not None  # run_job returns once the job has ended
        code = job.result_code
        assert code is not None  # the job has ended
        sim_s = backend.read_state().time_s - sim_t0
        payload: dict[str, Any] = {
            "ok": code is ResultCode.OK,
            "cell": cell.cell.cell,
            "task": controller.tasks[1].name,
            "params": params,
            "cycle_time_s": round(result.cycle_time_s, 4),
            "planned_cycle_time_s": round(job.planned_cycle_time_s or 0.0, 4),
            "max_tracking_error_m": round(job.tracking_error_m, 6),
            "result_code": int(code),
            "result_text": result.result_text,
            "retries": job.retries_used,
            "steps": self.rows_of(job, steps),
            "errors": [] if code is ResultCode.OK else [result.result_text],
            "real_time_factor": round(sim_s / wall_run_s, 1) if wall_run_s > 0 else None,
            "parts_end_m": parts_end(backend),
            "wall_plan_s": wall_plan_s,
            "wall_run_s": wall_run_s,
        }
        runner_done = controller.last_runner
        guard = runner_done.ctx.obstacles if runner_done is not None else None
        if guard is not None:
            payload["obstacles"] = guard.events
        if observer.not_dropped:
            payload["errors"].append(
                "--inject intrusion: no room on the path to drop the box clear of the arm"
                f" ({observer.not_dropped} x); nothing was dropped"
            )
        return RehearsedJob(code, payload)

    def close(self, save_map: str | None = None) -> None:
        """The feed closed, the watched zone's map saved (``save_map``), the cell closed."""
        if self.assembled.feed is not None:
            self.assembled.feed.close()
        if self.assembled.watch is not None and save_map:
            self.assembled.watch.map.save(save_map)
        self.controller.close()


def start_rehearsal(
    cell: LoadedCell,
    task: LoadedTask,
    backend: Any,
    out: Any,
    *,
    faults: Sequence[Fault] = (),
    recorder: Recording | None = None,
    rows_of: Callable[[Any, list[Step]], list[dict[str, Any]]] | None = None,
    log: Any = None,
    lookahead: bool = True,
) -> Rehearsal:
    """``task`` on ``cell`` assembled on the twin ``backend`` (a journal in memory, the
    eye and the watched zone on), set up and ready for its first job."""
    rehearsal = Rehearsal(None, backend, out, faults, recorder)  # type: ignore[arg-type]
    if rows_of is not None:
        rehearsal.rows_of = rows_of
    rehearsal.assembled = assemble_cell(
        cell,
        {1: task},
        backend,
        kind="sim",
        journal=Journal(":memory:"),
        log=log,
        on_step_start=rehearsal.on_step_start,
        lookahead=lookahead,
        eye=True,
        watched=True,
    )
    rehearsal.controller.setup()
    rehearsal.loop.step(3)
    return rehearsal


def parts_end(backend: Any) -> dict[str, list[float]]:
    """Where each part of the twin ended (world position, m); copies still waiting to be
    fed are not in the cell."""
    world = backend.world
    assert world is not None  # the run connected the backend
    parked = set(world.feeder.parked) if world.feeder is not None else set()
    return {
        p.name: [round(float(v), 5) for v in world.part_pose_world(p.name)[:3, 3]]
        for p in backend.description.parts
        if p.name not in parked
    }


def ready_within(loop: ControlLoop, controller: CellController, periods: int) -> bool:
    for _ in range(periods):
        if controller.status().ready:
            return True
        loop.step(1)
    return controller.status().ready


@dataclass
class FaultsAndProgress:
    """A control-loop observer: applies the injections when their moment comes, shows
    progress, and records the run for the report (``recorder`` None: no report)."""

    backend: Any
    pending: list[tuple[Fault, float]]
    recorder: Recording | None
    status: Any
    steps: list[Step]
    world: Any
    io_names: dict[str, str]  # IO name -> channel, for the report's IO lanes
    plc_back_at: float | None = None
    last_step: int = -1
    known: KnownScene | None = None  # the arm's solids, for where an injected intrusion may drop
    not_dropped: int = 0  # intrusions with no room on the path: none dropped

    def quiet_until_s(self, cell: CellController) -> float:
        """Until when (simulated s) :meth:`observe` has nothing to do while a motion
        streams: the next injection, the PLC coming back, the next report sample."""
        times = [at for _, at in self.pending]
        if self.plc_back_at is not None:
            times.append(self.plc_back_at)
        if self.recorder is not None:
            times.append(self.recorder.next_due_s)
        return min(times, default=float("inf"))

    def __call__(self, cell: CellController) -> None:
        self.observe(cell)

    def _drop_box(self, cell: CellController) -> bool:
        """``intrusion``: the twin's box appears on the path of the motion under way,
        where its TCP (else a wrist or the elbow) will be about two thirds of the way
        along the rest of it and where the box does not touch the arm as it stands
        (:func:`spot_ahead`). False: no room yet (the motion is not half done)."""
        from cellrunner.model.watch import INJECTED_BOX_M
        from cellrunner.perception.known import KnownScene
        from cellrunner.perception.path_check import spot_ahead

        streaming = cell.streaming()
        if streaming is None:
            return True
        approved, index = streaming
        q = approved.trajectory.q_rad
        if self.known is None:
            self.known = KnownScene(self.world)
        at = spot_ahead(self.known, q, index, max(INJECTED_BOX_M) / 2, INTRUSION_MARGIN_M)
        if at is None:  # try again a little later, until the motion is half done
            if index < len(q) // 2:
                return False
            self.not_dropped += 1
            return True
        T = np.eye(4)
        T[:3, 3] = at
        self.backend.inject_intrusion(T)
        return True

    def observe(self, cell: CellController) -> None:
        backend, recorder = self.backend, self.recorder
        state = backend.read_state()
        now = state.time_s
        for item in list(self.pending):
            inj, at = item
            if now >= at:
                self.pending.remove(item)
                if (
                    inj.fault == "plc_disconnect"
                ):  # the PLC watchdog holds the cell; the PLC comes back
                    cell.command("hold", HoldSource.PLC_WATCHDOG)
                    self.plc_back_at = now + PLC_OUTAGE_S
                elif inj.fault == "intrusion":
                    if not self._drop_box(cell):
                        self.pending.append((inj, now + INTRUSION_RETRY_S))
                else:
                    backend.inject_fault(inj.fault)
        if self.plc_back_at is not None and now >= self.plc_back_at and cell.command("unhold"):
            self.plc_back_at = None
        view = cell.job_view(records=False)
        if view is None or view.phase is None:
            return
        steps = self.steps
        if view.step != self.last_step:
            self.last_step = view.step
            step = steps[view.step - 1] if 0 < view.step <= len(steps) else None  # else on_error's
            self.status.update(
                escape(f"step {view.step}/{len(steps)} {step.kind} {step.name}")
                if step
                else "running"
            )
            if (
                recorder is not None
                and step is not None
                and step.kind in (StepKind.GRIP, StepKind.RELEASE)
            ):
                recorder.moment(f"step{view.step:02d}_{step.kind}", backend.world)
        if recorder is not None and recorder.due(now):
            recorder.sample(
                state,
                view.commanded_q_rad,
                self.world.kinematics.p_world_tcp(state.q_rad),
                self.io_names,
            )
