"""``cellrunner dry-run CELL TASK``: the real cell controller and job runner against the
MuJoCo twin, with faults made to happen physically (``--inject FAULT@STEP``)."""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

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
from cellrunner.errors import CellrunnerError
from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.journal import Journal
from cellrunner.model.codes import ResultCode
from cellrunner.model.step import StepKind
from cellrunner.report.recorder import RunRecorder

if TYPE_CHECKING:
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.execution.cell import CellController
    from cellrunner.model.step import Step

#: e-stop faults are released by the "operator" this long after they struck (sim s)
PLC_OUTAGE_S = 2.0


def _parts_end(backend: SimBackend) -> dict[str, list[float]]:
    """Where each part of the twin ended (world position, m)."""
    world = backend.world
    assert world is not None  # the run connected the backend
    return {
        p.name: [round(float(v), 5) for v in world.part_pose_world(p.name)[:3, 3]]
        for p in backend.description.parts
    }


def run(args: argparse.Namespace) -> int:
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    steps = expanded(cell, task, params)
    injections = parse_injections(args.inject, steps)
    if args.report or cell.cell.watch is not None or any(s.kind == StepKind.ALIGN for s in steps):
        from cellrunner.sim.mujoco_loader import enable_pictures

        # pictures (the report, an align step's camera) or depth (a watched cell, which
        # casts rays instead where there is no GL): choose the GL backend before MuJoCo
        # is imported, it reads it once
        enable_pictures()
    backend: SimBackend
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
                pending.append((inj, now + inj.delay_s))

    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure

        log = configure("json", cell.cell.cell)
    assembled = assemble_cell(
        cell,
        {1: task},
        "sim",
        journal=Journal(":memory:"),
        log=log,
        on_step_start=on_step_start,
        lookahead=not getattr(args, "per_period", False),
        eye=True,
        watched=True,
    )
    backend = cast("SimBackend", assembled.backend)  # "sim": the twin in this process
    controller, loop, world = assembled.controller, assembled.loop, assembled.world
    out = console()
    controller.setup()
    feed = assembled.feed
    loop.step(3)
    t0 = time.perf_counter()
    with out.status("planning", spinner="dots") as status:
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
            pending,
            recorder if report else None,
            status,
            steps,
            world,
            {**cell.cell.io.outputs, **cell.cell.io.inputs},
        )
        loop.add_observer(rehearsal)
        loop.step(1)  # the plan is picked up: the job runs (or ended with 103)
        view = controller.job_view(records=False) or controller.last_job
        planned_s = (view.planned_cycle_time_s or 0.0) if view is not None else 0.0
        loop.run_job(max_s=planned_s * 4 + 60)
        wall_run_s = time.perf_counter() - t_run
    if feed is not None:
        feed.close()
    if assembled.watch is not None and getattr(args, "save_map", None):
        assembled.watch.map.save(args.save_map)
    job = controller.last_job
    result = controller.status().last_result
    assert result is not None  # run_job returns once the job has ended
    code = ResultCode(result.result_code)
    rows = record_rows(job, steps)
    tracking = job.tracking_error_m if job else 0.0
    planned = (job.planned_cycle_time_s or 0.0) if job else 0.0
    sim_s = backend.read_state().time_s - sim_t0
    payload = {
        "ok": code is ResultCode.OK,
        "cell": cell.cell.cell,
        "task": task.name,
        "params": params,
        "cycle_time_s": round(result.cycle_time_s, 4),
        "planned_cycle_time_s": round(planned, 4),
        "max_tracking_error_m": round(tracking, 6),
        "result_code": int(code),
        "result_text": result.result_text,
        "retries": job.retries_used if job else 0,
        "steps": rows,
        "errors": [] if code is ResultCode.OK else [result.result_text],
        "injected": [i.spec for i in injections],
        "real_time_factor": round(sim_s / wall_run_s, 1) if wall_run_s > 0 else None,
        "parts_end_m": _parts_end(backend),
    }
    runner_done = controller.last_runner
    guard = runner_done.ctx.obstacles if runner_done is not None else None
    if guard is not None:
        payload["obstacles"] = guard.events
    if assembled.watch is not None:
        payload["depth_images"] = assembled.watch.images
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
    if args.json:
        emit_json(payload)
    else:
        out.print(
            step_table(
                f"dry-run {task.name} on {cell.cell.cell} (MuJoCo twin)", rows, ("attempts",)
            )
        )
        verdict = "[green]OK[/]" if code is ResultCode.OK else f"[bold red]{code.name}[/]"
        out.print(f"result {int(code)} {verdict}: {escape(result.result_text)}")
        out.print(
            f"cycle time {result.cycle_time_s:.2f} s simulated vs {planned:.2f} s planned; "
            f"max tracking error {tracking * 1000:.2f} mm; retries {payload['retries']}; "
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
            markup=False,
        )
    return 0 if code is ResultCode.OK else 1


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

    def _drop_box(self, cell: CellController) -> None:
        """``intrusion``: the twin's box appears on the path of the motion under way, where
        its TCP will be two thirds of the way along the rest of it."""
        streaming = cell.streaming()
        if streaming is None:
            return
        approved, index = streaming
        q = approved.trajectory.q_rad
        k = min(len(q) - 1, index + (len(q) - index) * 2 // 3)
        T = np.eye(4)
        T[:3, 3] = self.world.kinematics.p_world_tcp(q[k])
        self.backend.inject_intrusion(T)

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
                    self._drop_box(cell)
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
