"""``cellrunner run CELL TASK``: one job on the robot through ur_rtde, or on the twin
(``--backend sim``), through the same cell controller as ``serve``."""

from __future__ import annotations

import argparse
import contextlib
import sys

from cellrunner.backends.factory import backend_kind
from cellrunner.cli.common import console, emit_json, load, parse_params, record_rows, step_table
from cellrunner.cli.stopping import stop_on_signals
from cellrunner.errors import UsageError
from cellrunner.execution.assembly import assemble_cell
from cellrunner.model.codes import ResultCode
from cellrunner.record.attach import finish, record_to_file
from cellrunner.record.files import check_target


def run(args: argparse.Namespace) -> int:
    speed = getattr(args, "speed", 1.0)
    if not 0.0 < speed <= 1.0:
        raise UsageError(
            f"--speed {speed:g}: give a fraction of the approved pace, 0 < F <= 1 (e.g. 0.25)"
        )
    recording = check_target(args.record) if getattr(args, "record", None) else None
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    kind = backend_kind(cell, args.backend)
    if kind == "sim" and cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        enable_pictures()  # before MuJoCo is imported: an align step's camera renders
    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure

        log = configure("json", cell.cell.cell)
    stepping = getattr(args, "step", False)
    gate = None
    if stepping:
        from cellrunner.execution.pacing import EnterGate, describe_step

        gate = EnterGate(describe_step, on_end=lambda: controller.command("abort"))
    assembled = assemble_cell(
        cell,
        {1: task},
        kind,
        robot_host=args.robot_host,
        speed=speed,
        joined=not stepping,
        log=log,
        gate=gate,
        eye=True,
        image_source=getattr(args, "image_source", None),
        watched=True,
        depth_source=getattr(args, "depth_source", None),
    )
    controller, loop = assembled.controller, assembled.loop
    recorder = record_to_file(assembled, recording) if recording else None
    out = console()
    # SIGTERM and Ctrl-C: the arm stopped, the job closed with 107 and reported, exit 1,
    # within 2 s even with a controller that does not answer (cellrunner.cli.stopping)
    signals = contextlib.ExitStack()
    stopping = signals.enter_context(stop_on_signals(exit_code=1))
    controller.setup()
    try:
        if assembled.feed is not None:
            assembled.feed.start()
        loop.step(5)
        ticket = controller.start_job(1, params, "", "cli")
        if not ticket.accepted:
            sys.stderr.write(f"cellrunner run: job refused: {ticket.message}\n")
            return 1
        pace = f" at {speed:g} x speed" if speed != 1.0 else ""
        if gate is not None:  # no spinner: the operator reads each step's preview
            out.print(f"running {task.name} on the {kind} backend{pace}, one step at a time")
            gate.start()
            loop.run_job(max_s=24 * 3600.0, stop=stopping.event)
        else:
            with out.status(f"running {task.name} on the {kind} backend{pace}", spinner="dots"):
                loop.run_job(max_s=3600.0 / speed, stop=stopping.event)
        if stopping.event.is_set():
            controller.shutdown(stopping.reason)
        job = controller.last_job
        result = controller.status().last_result
    finally:
        if assembled.feed is not None:
            assembled.feed.close()
        controller.close()
        if recorder is not None and recording is not None:
            sys.stderr.write(finish(recorder, recording) + "\n")
        signals.close()
    assert result is not None and job is not None  # run_job returns once the job has ended
    code = job.result_code  # typed: a number only in the JSON and the exit status
    assert code is not None  # the job has ended
    rows = record_rows(job)
    payload = {
        "ok": code is ResultCode.OK,
        "cell": cell.cell.cell,
        "task": task.name,
        "params": params,
        "cycle_time_s": round(result.cycle_time_s, 4),
        "result_code": int(code),
        "result_text": result.result_text,
        "job_id": result.job_id,
        "backend": kind,
        "steps": rows,
        "errors": [] if code is ResultCode.OK else [result.result_text],
    }
    if assembled.watch is not None:
        runner = controller.last_runner
        guard = runner.ctx.obstacles if runner is not None else None
        payload["obstacles"] = list(guard.events) if guard is not None else []
        payload["depth_images"] = assembled.watch.images
    if args.json:
        emit_json(payload)
    else:
        out.print(step_table(f"run {task.name} on {cell.cell.cell} ({kind})", rows, ("attempts",)))
        out.print(
            f"job {result.job_id}: result {int(code)} {result.result_text}; cycle {result.cycle_time_s:.2f} s",
            markup=False,
        )
    if code is ResultCode.ROBOT_CONNECTION_LOST:
        return 3
    return 0 if code is ResultCode.OK else 1
