"""``cellrunner dry-run CELL TASK``: the real cell controller and job runner against the
MuJoCo twin, with faults made to happen physically (``--inject FAULT@STEP``)."""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rich.markup import escape

from cellrunner.cli.common import (
    console,
    emit_json,
    expanded,
    load,
    parse_params,
    record_rows,
    step_table,
)
from cellrunner.cli.faults import Injection, parse_injections
from cellrunner.cli.slots import whole_run
from cellrunner.errors import CellrunnerError, UsageError
from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.journal import Journal
from cellrunner.model.codes import ResultCode
from cellrunner.model.step import StepKind
from cellrunner.report.recorder import RunRecorder

if TYPE_CHECKING:
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.execution.cell import CellController
    from cellrunner.execution.loop import ControlLoop
    from cellrunner.model.step import Step
    from cellrunner.perception.known import KnownScene

#: e-stop faults are released by the "operator" this long after they struck (sim s)
PLC_OUTAGE_S = 2.0


def _parts_end(backend: SimBackend) -> dict[str, list[float]]:
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


def run(args: argparse.Namespace) -> int:
    cell, task = load(args.cell, args.task)
    pairs, whole = whole_run(getattr(args, "slots", None), args.param, task)
    params = parse_params(pairs, task)
    jobs = [params] if whole is None else [{**params, whole[0]: v} for v in whole[1]]
    if whole is not None and args.report:
        raise UsageError("--report rehearses one job; drop --slots (or the -p range) for it")
    steps = expanded(cell, task, jobs[0])
    injections = parse_injections(args.inject, steps)
    if args.report or cell.cell.watch is not None or cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        # before MuJoCo is imported: it reads its GL backend once (a watched cell's depth
        # cameras cast rays instead where there is none; an align step's camera renders)
        enable_pictures()
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.sim.from_cell import rehearsal_description

    # the earlier slots of a place pattern already filled, a part fed before each job of a
    # whole run (SPEC section 12)
    backend = SimBackend(rehearsal_description(cell, task, jobs[0], len(jobs)))
    pending: list[tuple[Injection, float]] = []
    report = Path(args.report) if args.report else None
    recorder = RunRecorder()

    def on_step_start(step: Step, attempt: int) -> None:
        now = backend.read_state().time_s
        recorder.mark(now, step)
        for inj in injections:
            if (
                inj.step_index == step.index
                and attempt == 1
                and all(p[0] is not inj for p in pending)
            ):
                moves_s = controller.planned_motion_s(step)
                pending.append((inj, now + inj.delay_within_s(moves_s)))

    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure

        log = configure("json", cell.cell.cell)
    assembled = assemble_cell(
        cell,
        {1: task},
        backend,
        kind="sim",
        journal=Journal(":memory:"),
        log=log,
        on_step_start=on_step_start,
        lookahead=not getattr(args, "per_period", False),
        eye=True,
        watched=True,
    )
    controller, loop, world = assembled.controller, assembled.loop, assembled.world
    zone, feed = assembled.watch, assembled.feed
    out = console()
    controller.setup()
    loop.step(3)
    job_run = _JobRun(controller, loop, backend, world, out, pending, recorder if report else None)
    payloads = []
    for job_params in jobs:
        if backend.world is not None and backend.world.feeder is not None:
            backend.feed_parts()  # the conveyor brings the next part (sim: feed)
        job_steps = expanded(cell, task, job_params)
        payload = job_run.rehearse(job_params, job_steps)
        payload["injected"] = [i.spec for i in injections]
        payloads.append(payload)
    if feed is not None:
        feed.close()
    if zone is not None and getattr(args, "save_map", None):
        zone.map.save(args.save_map)
    if whole is not None:
        controller.close()
        return _whole_run_output(args, cell.cell.cell, task.name, whole[0], payloads, out)
    payload, rows = payloads[0], payloads[0]["steps"]
    code = ResultCode(payload["result_code"])
    if zone is not None:
        payload["depth_images"] = zone.images
        intruders = backend.world.intruders if backend.world is not None else None
        payload["intruders_touched"] = sorted(intruders.touched) if intruders else []
    has_pictures = True
    if report is not None:
        from cellrunner.report import write_report

        assert backend.world is not None  # the run connected the twin
        has_pictures = write_report(
            report,
            recorder,
            payload,
            sim_world=backend.world,
            world=world,
            task=task,
            params=params,
            step_rows=rows,
            obstacles_m=(
                zone.map.centres(np.flatnonzero(zone.ever_occupied)) if zone is not None else None
            ),
        )
    runner = controller.last_runner  # finished: the control loop no longer touches it
    trace = list(runner.ctx.notes.get("force_trace", [])) if runner else []
    if report is not None and trace:
        from cellrunner.report.plots import plot_wrist_force

        limits = {
            s.index: s.args.force if s.kind == StepKind.MOVE_UNTIL_CONTACT else s.args.force.max
            for s in steps
            if s.kind in (StepKind.MOVE_UNTIL_CONTACT, StepKind.INSERT)
        }
        plot_wrist_force(
            Path(report) / "wrist_force.png",
            trace,
            limits,
            title=f"{task.name}: wrist force in the force steps",
        )
    controller.close()
    wall_plan_s, wall_run_s = payload.pop("wall_plan_s"), payload.pop("wall_run_s")
    if args.json:
        emit_json(payload)
    else:
        out.print(
            step_table(
                f"dry-run {task.name} on {cell.cell.cell} (MuJoCo twin)", rows, ("attempts",)
            )
        )
        verdict = "[green]OK[/]" if code is ResultCode.OK else f"[bold red]{code.name}[/]"
        out.print(f"result {int(code)} {verdict}: {escape(payload['result_text'])}")
        out.print(
            f"cycle time {payload['cycle_time_s']:.2f} s simulated vs "
            f"{payload['planned_cycle_time_s']:.2f} s planned; "
            f"max tracking error {payload['max_tracking_error_m'] * 1000:.2f} mm; "
            f"retries {payload['retries']}; "
            f"planning {wall_plan_s:.2f} s, simulation {wall_run_s:.2f} s wall "
            f"({payload['real_time_factor']}x real time)"
        )
        if report is not None:
            out.print(f"report written to {report}/index.html", markup=False)
    if not has_pictures:
        from cellrunner.sim.mujoco_loader import GL_ADVICE, no_gl_reason

        out.print(
            f"no pictures in the report: {no_gl_reason()} ({GL_ADVICE} gives one)",
            soft_wrap=True,
        )
    return 0 if code is ResultCode.OK else 1


@dataclass
class _JobRun:
    """One twin and its cell controller, rehearsing jobs one after the other (the parts
    staying where each job put them)."""

    controller: CellController
    loop: ControlLoop
    backend: Any
    world: Any
    out: Any
    pending: list[tuple[Injection, float]]
    recorder: RunRecorder | None

    def _until_ready(self) -> None:
        """After a job: Complete becomes Idle by itself; a stopped cell is reset (the
        operator's Reset between two rehearsed jobs)."""
        rate = int(self.backend.description.rate_hz)
        if _ready_within(self.loop, self.controller, rate):
            return
        self.controller.command("reset")
        if not _ready_within(self.loop, self.controller, 10 * rate):
            state = self.controller.status().state_name
            raise CellrunnerError(f"the cell did not come back to Idle after a job (state {state})")

    def rehearse(self, params: dict[str, Any], steps: list[Step]) -> dict[str, Any]:
        """Run one job with ``params`` to its end; its JSON payload (with the wall times
        ``wall_plan_s``/``wall_run_s``)."""
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
            rehearsal = _Rehearsal(
                backend,
                self.pending,
                self.recorder,
                status,
                steps,
                self.world,
                {**cell.cell.io.outputs, **cell.cell.io.inputs},
            )
            loop.add_observer(rehearsal)
            loop.step(1)  # the plan is picked up: the job runs (or ended with 103)
            view = controller.job_view(records=False) or controller.last_job
            planned_s = (view.planned_cycle_time_s or 0.0) if view is not None else 0.0
            loop.run_job(max_s=planned_s * 4 + 60)
            loop.observers.remove(rehearsal)
            wall_run_s = time.perf_counter() - t_run
        job = controller.last_job
        result = controller.status().last_result
        assert result is not None  # run_job returns once the job has ended
        code = ResultCode(result.result_code)
        sim_s = backend.read_state().time_s - sim_t0
        payload: dict[str, Any] = {
            "ok": code is ResultCode.OK,
            "cell": cell.cell.cell,
            "task": controller.tasks[1].name,
            "params": params,
            "cycle_time_s": round(result.cycle_time_s, 4),
            "planned_cycle_time_s": round((job.planned_cycle_time_s or 0.0) if job else 0.0, 4),
            "max_tracking_error_m": round(job.tracking_error_m if job else 0.0, 6),
            "result_code": int(code),
            "result_text": result.result_text,
            "retries": job.retries_used if job else 0,
            "steps": record_rows(job, steps),
            "errors": [] if code is ResultCode.OK else [result.result_text],
            "real_time_factor": round(sim_s / wall_run_s, 1) if wall_run_s > 0 else None,
            "parts_end_m": _parts_end(backend),
            "wall_plan_s": wall_plan_s,
            "wall_run_s": wall_run_s,
        }
        runner_done = controller.last_runner
        guard = runner_done.ctx.obstacles if runner_done is not None else None
        if guard is not None:
            payload["obstacles"] = guard.events
        if rehearsal.not_dropped:
            payload["errors"].append(
                "--inject intrusion: no room on the path to drop the box clear of the arm"
                f" ({rehearsal.not_dropped} x); nothing was dropped"
            )
        return payload


def _ready_within(loop: ControlLoop, controller: CellController, periods: int) -> bool:
    for _ in range(periods):
        if controller.status().ready:
            return True
        loop.step(1)
    return controller.status().ready


def _whole_run_output(
    args: argparse.Namespace,
    cell_name: str,
    task_name: str,
    param: str,
    payloads: list[dict[str, Any]],
    out: Any,
) -> int:
    """A row per job (SPEC section 12); ``--json``: one object with a ``jobs`` list."""
    ok = all(p["result_code"] == 0 for p in payloads)
    first_failed = next((p for p in payloads if p["result_code"] != 0), None)
    jobs = [
        {k: v for k, v in p.items() if k not in ("wall_plan_s", "wall_run_s", "cell", "task")}
        for p in payloads
    ]
    if args.json:
        emit_json(
            {
                "ok": ok,
                "cell": cell_name,
                "task": task_name,
                "param": param,
                "result_code": first_failed["result_code"] if first_failed else 0,
                "result_text": first_failed["result_text"] if first_failed else "OK",
                "jobs": jobs,
                "cycle_time_s": round(sum(j["cycle_time_s"] for j in jobs), 4),
                "errors": [
                    f"{param}={j['params'][param]}: {j['result_text']}"
                    for j in jobs
                    if j["result_code"] != 0
                ],
                "parts_end_m": payloads[-1]["parts_end_m"],
            }
        )
        return 0 if ok else 1
    from rich.table import Table

    table = Table(
        title=f"dry-run {task_name} on {cell_name}, {len(jobs)} jobs in one twin",
        title_justify="left",
        pad_edge=False,
    )
    for name, justify in (
        ("job", "right"),
        (param, "right"),
        ("result", "right"),
        ("cycle s", "right"),
        ("planned s", "right"),
        ("message", "left"),
    ):
        table.add_column(name, justify=justify, overflow="fold")  # type: ignore[arg-type]
    for i, j in enumerate(jobs, 1):
        color = "green" if j["result_code"] == 0 else "bold red"
        table.add_row(
            str(i),
            str(j["params"][param]),
            f"[{color}]{j['result_code']}[/]",
            f"{j['cycle_time_s']:.2f}",
            f"{j['planned_cycle_time_s']:.2f}",
            escape(j["result_text"]),
        )
    out.print(table)
    failed = sum(1 for j in jobs if j["result_code"] != 0)
    out.print(
        f"{len(jobs) - failed} of {len(jobs)} jobs OK; "
        f"{sum(j['cycle_time_s'] for j in jobs):.2f} s simulated in all"
    )
    return 0 if ok else 1


#: an injected intrusion drops at least this far from the arm as it stands (m)
INTRUSION_MARGIN_M = 0.02
#: with no room for it yet, an intrusion is tried again this much later (s)
INTRUSION_RETRY_S = 0.05


@dataclass
class _Rehearsal:
    """A control-loop observer: applies the injections when their moment comes, shows
    progress, and records the run for the report (``recorder`` None: no report)."""

    backend: Any
    pending: list[tuple[Injection, float]]
    recorder: RunRecorder | None
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
        from cellrunner.perception.known import KnownScene
        from cellrunner.perception.path_check import spot_ahead
        from cellrunner.sim.from_cell import INJECTED_BOX_M

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
                    cell.command("hold")
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
