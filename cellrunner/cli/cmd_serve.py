"""``cellrunner serve CELL``: production. The PLC interface up, jobs on trigger, the
journal, until SIGTERM (which stops motion, closes the running job with 107, exits 0)."""

from __future__ import annotations

import signal
import sys
import threading
import time

from cellrunner.backends.factory import backend_kind, make_backend
from cellrunner.cli.logs import configure
from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
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
    try:
        _loop(controller, stop, paced=kind == "sim")
    finally:
        controller.shutdown("cellrunner stopped (SIGTERM)")
        if service is not None:
            service.stop()
        controller.close()
        log.info("stopped")
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


def _loop(controller: CellController, stop: threading.Event, *, paced: bool) -> None:
    """One tick per controller period; the twin in-process is paced to the wall clock."""
    period = 1.0 / controller.backend.rate_hz
    next_t = time.monotonic()
    while not stop.is_set():
        controller.backend.wait_period()
        controller.tick()
        if paced:
            next_t += period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            elif delay < -0.5:
                next_t = time.monotonic()  # fell behind: don't try to catch up in a burst
