"""``cellrunner run CELL TASK``: one job on the robot through ur_rtde, or on the twin
(``--backend sim``), through the same cell controller as ``serve``."""

from __future__ import annotations

import sys

from cellrunner.backends.factory import backend_kind, make_backend
from cellrunner.cli.common import console, emit_json, load, parse_params, record_rows, step_table
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner
from cellrunner.model.codes import ResultCode


def run(args) -> int:
    cell, task = load(args.cell, args.task)
    params = parse_params(args.param, task)
    from cellrunner.planning.world import CellWorld

    kind = backend_kind(cell, args.backend)
    backend = make_backend(cell, kind, args.robot_host)
    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure
        log = configure("json", cell.cell.cell)
    controller = CellController(cell, {1: task}, backend, Journal(cell.resolve(cell.cell.journal)),
                                job_planner(CellWorld(cell)), log=log, wait_for_unhold=False)
    out = console()
    controller.setup()
    loop = ControlLoop(controller)
    try:
        loop.step(5)
        ticket = controller.start_job(1, params, "", "cli")
        if not ticket.accepted:
            sys.stderr.write(f"cellrunner run: job refused: {ticket.message}\n")
            return 1
        with out.status(f"running {task.name} on the {kind} backend", spinner="dots"):
            loop.run_job(max_s=3600.0)
        job = controller.last_job
        result = controller.status().last_result
    finally:
        controller.close()
    code = ResultCode(result.result_code)
    rows = record_rows(job)
    payload = {"ok": code is ResultCode.OK, "cell": cell.cell.cell, "task": task.name, "params": params,
               "cycle_time_s": round(result.cycle_time_s, 4), "result_code": int(code),
               "result_text": result.result_text, "job_id": result.job_id, "backend": kind, "steps": rows,
               "errors": [] if code is ResultCode.OK else [result.result_text]}
    if args.json:
        emit_json(payload)
    else:
        out.print(step_table(f"run {task.name} on {cell.cell.cell} ({kind})", rows, ("attempts",)))
        out.print(f"job {result.job_id}: result {int(code)} {result.result_text}; cycle {result.cycle_time_s:.2f} s")
    if code is ResultCode.ROBOT_CONNECTION_LOST:
        return 3
    return 0 if code is ResultCode.OK else 1
