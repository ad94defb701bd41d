"""``cellrunner run CELL TASK``: one job on the robot through ur_rtde, or on the twin
(``--backend sim``), through the same cell controller as ``serve``."""

from __future__ import annotations

import argparse
import contextlib
import sys
from typing import TYPE_CHECKING, Any

from cellrunner.backends.factory import backend_kind
from cellrunner.cli.common import console, emit_json, load, parse_params, record_rows, step_table
from cellrunner.cli.stopping import stop_on_signals
from cellrunner.errors import UsageError
from cellrunner.execution.assembly import AssembledCell, assemble_cell
from cellrunner.execution.run_once import run_one_job
from cellrunner.model.cellport import JobResult
from cellrunner.model.codes import ResultCode
from cellrunner.record.attach import finish, record_to_file
from cellrunner.record.files import check_target

if TYPE_CHECKING:
    from cellrunner.execution.pacing import EnterGate
    from cellrunner.model.load import LoadedCell, LoadedTask


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
    assembled, gate = _assemble(args, cell, task, kind, speed)
    controller = assembled.controller
    recorder = record_to_file(assembled, recording) if recording else None
    out = console()
    pace = f" at {speed:g} x speed" if speed != 1.0 else ""

    def announce() -> contextlib.AbstractContextManager[Any]:
        if gate is not None:  # no spinner: the operator reads each step's preview
            return contextlib.nullcontext()
        return out.status(f"running {task.name} on the {kind} backend{pace}", spinner="dots")

    def first_step() -> None:
        if gate is not None:
            out.print(f"running {task.name} on the {kind} backend{pace}, one step at a time")
            gate.start()

    def close_recording() -> None:
        if recorder is not None and recording is not None:
            sys.stderr.write(finish(recorder, recording) + "\n")

    # SIGTERM and Ctrl-C: the arm stopped, the job closed with 107 and reported, exit 1,
    # within 2 s even with a controller that does not answer (cellrunner.cli.stopping)
    signals = contextlib.ExitStack()
    stopping = signals.enter_context(stop_on_signals(exit_code=1))
    try:
        ran = run_one_job(
            assembled,
            params,
            stop=stopping.event,
            stop_reason=lambda: stopping.reason,
            max_s=24 * 3600.0 if gate is not None else 3600.0 / speed,
            on_refused=lambda why: sys.stderr.write(f"cellrunner run: job refused: {why}\n"),
            before=first_step,
            while_running=announce,
            on_close=close_recording,
        )
    finally:
        signals.close()
    if ran.refused:
        return 1
    job, result = ran.job, ran.result
    assert result is not None and job is not None  # run_job returns once the job has ended
    code = job.result_code  # typed: a number only in the JSON and the exit status
    assert code is not None  # the job has ended
    rows = record_rows(job)
    payload = _payload(cell.cell.cell, task.name, params, kind, code, result, rows)
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


def _assemble(
    args: argparse.Namespace, cell: LoadedCell, task: LoadedTask, kind: str, speed: float
) -> tuple[AssembledCell, EnterGate | None]:
    """The cell put together for ``run`` (not connected), and ``--step``'s gate."""
    built: list[AssembledCell] = []  # the gate's Abort reaches the controller built below
    if kind == "sim" and cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        enable_pictures()  # before MuJoCo is imported: an align step's camera renders
    log = None
    if args.log_format == "json":
        from cellrunner.cli.logs import configure

        log = configure("json", cell.cell.cell)
    stepping = getattr(args, "step", False)
    gate: EnterGate | None = None
    if stepping:
        from cellrunner.execution.pacing import EnterGate, describe_step

        gate = EnterGate(describe_step, on_end=lambda: built[0].controller.command("abort"))
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
    built.append(assembled)
    return assembled, gate


def _payload(
    cell: str,
    task: str,
    params: dict[str, Any],
    kind: str,
    code: ResultCode,
    result: JobResult,
    rows: list[dict[str, Any]],
) -> dict[str, Any]:
    """``run --json``'s fields (SPEC 7), but the watched zone's."""
    return {
        "ok": code is ResultCode.OK,
        "cell": cell,
        "task": task,
        "params": params,
        "cycle_time_s": round(result.cycle_time_s, 4),
        "result_code": int(code),
        "result_text": result.result_text,
        "job_id": result.job_id,
        "backend": kind,
        "steps": rows,
        "errors": [] if code is ResultCode.OK else [result.result_text],
    }
