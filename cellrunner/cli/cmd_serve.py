"""``cellrunner serve CELL``: production. The PLC interface up, jobs on trigger, the
journal, until SIGTERM (which stops motion, closes the running job with 107, exits 0)."""

from __future__ import annotations

import signal
import sys
import threading

from cellrunner.backends.factory import backend_kind, make_backend
from cellrunner.cli.logs import configure
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner, warm_up
from cellrunner.model.load import load_cell, load_task, serve_file_warnings


def run(args) -> int:
    cell = load_cell(args.cell)
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    for w in cell.warnings + serve_file_warnings(cell):
        sys.stderr.write(f"{w}\n")
    log = configure(args.log_format, cell.cell.cell)
    kind = backend_kind(cell, args.backend)
    backend = make_backend(cell, kind, args.robot_host)
    from cellrunner.planning.world import CellWorld
    world = CellWorld(cell)
    warm_up(world)  # before READY: the first job is acknowledged as fast as any other
    _load_planning_libraries()
    # the planning thread is CPU-bound; hand the GIL over every 1 ms (Python's default is
    # 5 ms) so the PLC threads answer promptly while a job plans
    sys.setswitchinterval(0.001)
    controller = CellController(cell, tasks, backend, Journal(cell.resolve(cell.cell.journal)),
                                job_planner(world), log=log, wait_for_unhold=True,
                                on_job_start=getattr(backend, "feed_parts", None))
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    controller.setup()
    service = _plc_service(controller, cell)
    log.info("serving", backend=kind, tasks={n: t.name for n, t in tasks.items()},
             modbus=getattr(service, "modbus_address", None) if service else None)
    reason = "cellrunner stopped (SIGTERM)"
    try:
        ControlLoop(controller, realtime=kind == "sim").run(stop)
    except Exception as exc:  # a bug in the control loop: close the job saying so, then exit 1
        reason = f"cellrunner failed: {type(exc).__name__}: {exc}"
        log.exception("control_loop_failed", error=str(exc))
        raise
    finally:
        controller.shutdown(reason)
        if service is not None:
            service.stop()
        controller.close()
        log.info("stopped", reason=reason)
    return 0


def _plc_service(controller: CellController, cell):
    plc = cell.cell.plc
    if plc.modbus is None and plc.opcua is None:
        return None
    from cellrunner.plc.service import PlcService
    pki = cell.resolve(plc.opcua.pki) if plc.opcua and plc.opcua.pki else cell.resolve(cell.cell.journal).parent / "pki"
    service = PlcService(controller, plc, resolve=cell.resolve, pki_dir=pki, cell_name=cell.cell.cell)
    service.start()
    return service


def _load_planning_libraries() -> None:
    """Load OMPL and TOPP-RA now, before the PLC link is up: loading them holds Python's
    GIL for tenths of a second, which during the first job would stall every thread of
    the process, the PLC heartbeat among them."""
    import ompl.geometric  # noqa: F401
    import toppra  # noqa: F401
