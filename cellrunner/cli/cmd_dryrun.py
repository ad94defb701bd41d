"""``cellrunner dry-run CELL TASK``: the real cell controller and job runner against the
MuJoCo twin, with faults made to happen physically (``--inject FAULT@STEP``)."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

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
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner
from cellrunner.model.codes import ResultCode

#: e-stop faults are released by the "operator" this long after they struck (sim s)
PLC_OUTAGE_S = 2.0
#: written into a report that has plots but no rendered pictures
NO_PICTURES = "NO_PICTURES.txt"


@dataclass
class _Recorder:
    """What the report needs: samples of the run, and pictures at key moments."""

    report: Path | None
    t: list = field(default_factory=list)
    q: list = field(default_factory=list)
    qd: list = field(default_factory=list)
    q_cmd: list = field(default_factory=list)
    tcp: list = field(default_factory=list)
    marks: list = field(default_factory=list)
    pictures: list = field(default_factory=list)


def run(args) -> int:
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    steps = expanded(cell, task, params)
    injections = parse_injections(args.inject, steps)
    if args.report:
        from cellrunner.backends.sim._mj import enable_pictures
        enable_pictures()  # before MuJoCo is imported: it reads its GL backend once
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.backends.sim.from_cell import description_of
    from cellrunner.planning.world import CellWorld

    world = CellWorld(cell)
    backend = SimBackend(description_of(cell))
    pending: list[tuple[Injection, float]] = []
    recorder = _Recorder(Path(args.report) if args.report else None)

    def on_step_start(step, attempt):
        now = backend.read_state().time_s
        recorder.marks.append((now, f"{step.index} {step.kind}"))
        for inj in injections:
            if inj.step_index == step.index and attempt == 1 and all(p[0] is not inj for p in pending):
                pending.append((inj, now + inj.delay_s))

    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure
        log = configure("json", cell.cell.cell)
    controller = CellController(cell, {1: task}, backend, Journal(":memory:"), job_planner(world), log=log,
                                wait_for_unhold=False, on_step_start=on_step_start)
    out = console()
    controller.setup()
    loop = ControlLoop(controller)
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
        rehearsal = _Rehearsal(backend, pending, recorder, status, steps, world)
        loop.add_observer(rehearsal.observe)
        loop.step(1)  # the plan is picked up: the job runs (or ended with 103)
        view = controller.job_view(records=False) or controller.last_job
        planned_s = (view.planned_cycle_time_s or 0.0) if view is not None else 0.0
        loop.run_job(max_s=planned_s * 4 + 60)
        wall_run_s = time.perf_counter() - t_run
    job = controller.last_job
    result = controller.status().last_result
    code = ResultCode(result.result_code)
    rows = record_rows(job, steps)
    tracking = job.tracking_error_m if job else 0.0
    planned = (job.planned_cycle_time_s or 0.0) if job else 0.0
    sim_s = backend.read_state().time_s - sim_t0
    payload = {"ok": code is ResultCode.OK, "cell": cell.cell.cell, "task": task.name, "params": params,
               "cycle_time_s": round(result.cycle_time_s, 4), "planned_cycle_time_s": round(planned, 4),
               "max_tracking_error_m": round(tracking, 6), "result_code": int(code),
               "result_text": result.result_text, "retries": job.retries_used if job else 0,
               "steps": rows, "errors": [] if code is ResultCode.OK else [result.result_text],
               "injected": [i.spec for i in injections],
               "real_time_factor": round(sim_s / wall_run_s, 1) if wall_run_s > 0 else None}
    has_pictures = _write_report(recorder, payload, backend) if recorder.report is not None else True
    controller.close()
    if args.json:
        emit_json(payload)
    else:
        out.print(step_table(f"dry-run {task.name} on {cell.cell.cell} (MuJoCo twin)", rows, ("attempts",)))
        verdict = "[green]OK[/]" if code is ResultCode.OK else f"[bold red]{code.name}[/]"
        out.print(f"result {int(code)} {verdict}: {result.result_text}")
        out.print(f"cycle time {result.cycle_time_s:.2f} s simulated vs {planned:.2f} s planned; "
                  f"max tracking error {tracking * 1000:.2f} mm; retries {payload['retries']}; "
                  f"planning {wall_plan_s:.2f} s, simulation {wall_run_s:.2f} s wall "
                  f"({payload['real_time_factor']}x real time)")
        if recorder.report is not None:
            out.print(f"report written to {recorder.report}/")
    if not has_pictures:
        from cellrunner.backends.sim._mj import GL_ADVICE
        out.print(f"no pictures in the report: no OpenGL backend here ({GL_ADVICE} gives one)", soft_wrap=True)
    return 0 if code is ResultCode.OK else 1


@dataclass
class _Rehearsal:
    """A control-loop observer: applies the injections when their moment comes, shows
    progress, and records the run for the report."""

    backend: Any
    pending: list
    recorder: _Recorder
    status: Any
    steps: list
    world: Any
    plc_back_at: float | None = None
    last_step: int = -1
    n: int = 0

    def observe(self, cell: CellController) -> None:
        backend, recorder = self.backend, self.recorder
        state = backend.read_state()
        now = state.time_s
        for item in list(self.pending):
            inj, at = item
            if now >= at:
                self.pending.remove(item)
                if inj.fault == "plc_disconnect":  # the PLC watchdog holds the cell; the PLC comes back
                    cell.command("hold")
                    self.plc_back_at = now + PLC_OUTAGE_S
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
            self.status.update(f"step {view.step}/{len(steps)} {step.kind} {step.name}" if step else "running")
            if recorder.report is not None and step is not None and step.kind in ("grip", "release"):
                recorder.pictures.append((f"step{view.step:02d}_{step.kind}", _snapshot(backend)))
        if self.n % max(1, int(backend.rate_hz / 50)) == 0 and recorder.report is not None:
            recorder.t.append(now)
            recorder.q.append(state.q_rad.copy())
            recorder.qd.append(state.qd_rad_s.copy())
            recorder.q_cmd.append(view.commanded_q_rad if view.commanded_q_rad is not None else state.q_rad.copy())
            recorder.tcp.append(self.world.kinematics.T_world_tcp(state.q_rad)[:3, 3])
        self.n += 1


def _snapshot(backend) -> np.ndarray | None:
    from cellrunner.backends.sim.render import CellRenderer, RenderUnavailable
    try:
        with CellRenderer(backend.world, 800, 600) as renderer:
            return renderer.render()
    except RenderUnavailable:
        return None


def _write_report(recorder: _Recorder, payload: dict, backend) -> bool:
    """Write the report folder; returns whether it holds rendered pictures."""
    from cellrunner.backends.sim import render

    folder = recorder.report
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "result.json").write_text(json.dumps(payload, indent=2))
    pictures = list(recorder.pictures)
    pictures.append(("end", _snapshot(backend)))
    written = []
    for name, image in pictures:
        if image is None:
            continue
        path = folder / f"{name}.png"
        import matplotlib.pyplot as plt
        plt.imsave(path, image)
        written.append(path.name)
    if recorder.t:
        t = np.array(recorder.t) - recorder.t[0]
        marks = [(m - recorder.t[0], label) for m, label in recorder.marks]
        render.plot_joints(folder / "joints.png", t, np.array(recorder.q), np.array(recorder.qd),
                           q_ref_rad=np.array(recorder.q_cmd), title=f"{payload['task']}: joints", marks=marks)
        render.plot_tcp_path(folder / "tcp_path.png", np.array(recorder.tcp), title=f"{payload['task']}: TCP path")
        written += ["joints.png", "tcp_path.png"]
    has_pictures = any(name.endswith(".png") and name not in ("joints.png", "tcp_path.png") for name in written)
    (folder / NO_PICTURES).unlink(missing_ok=True)
    if not has_pictures:
        from cellrunner.backends.sim._mj import GL_ADVICE
        (folder / NO_PICTURES).write_text(f"no offscreen OpenGL backend here: {GL_ADVICE} gives one\n")
    return has_pictures
