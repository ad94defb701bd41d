"""``cellrunner serve CELL``: production. The PLC interface up, jobs on trigger, the
journal, until SIGTERM (which stops motion, closes the running job with 107, exits 0)."""

from __future__ import annotations

import argparse
import contextlib
import functools
import sys
from typing import TYPE_CHECKING, Any

from cellrunner.backends.factory import backend_kind
from cellrunner.cli.logs import configure
from cellrunner.cli.stopping import stop_on_signals
from cellrunner.errors import UsageError
from cellrunner.execution.assembly import assemble_cell
from cellrunner.execution.journal import is_database_url
from cellrunner.execution.journal_open import cell_journal
from cellrunner.execution.serving import Closer, serve
from cellrunner.model.load import (
    LoadedCell,
    LoadedTask,
    load_cell,
    load_task,
    serve_file_warnings,
)
from cellrunner.plc.service import raise_thread_priority

if TYPE_CHECKING:
    from cellrunner.execution.assembly import AssembledCell
    from cellrunner.execution.cell import CellController
    from cellrunner.execution.context import EventLog
    from cellrunner.execution.serve_faults import ServeFaults
    from cellrunner.plc.service import PlcService
    from cellrunner.record.collector import Collector
    from cellrunner.web.server import StatusServer


#: what a stopped serve gives the journal's last writes, s: with the recorder's 0.8 s it
#: stays inside cellrunner.cli.stopping.GRACE_S (1.5 s)
JOURNAL_STOP_FLUSH_S = 0.5


def run(args: argparse.Namespace) -> int:
    http = None
    if getattr(args, "http", None):
        from cellrunner.web.server import parse_address

        http = parse_address(args.http)  # a bad address is exit 2 before anything starts
    record = getattr(args, "record", None)
    if record:
        from cellrunner.record.files import JobFolder

        folder = JobFolder.check(record, "." + args.record_format)
    cell = load_cell(args.cell)
    tasks = {n: load_task(cell.resolve(p), cell) for n, p in cell.cell.tasks.items()}
    for w in cell.warnings + serve_file_warnings(cell):
        sys.stderr.write(f"{w}\n")
    log = configure(args.log_format, cell.cell.cell)
    # Every thread of this process runs at the PLC threads' priority (those started from
    # here inherit it): a PLC thread waits for the GIL, so a lower-priority holder (the
    # control loop, the robot's state reader, planning) preempted by other processes would
    # stall the heartbeat for as long as the OS keeps it off the CPU.
    raise_thread_priority()
    kind = backend_kind(cell, args.backend)
    faults = _faults(args, kind, log)
    if kind == "sim" and cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        enable_pictures()  # before MuJoCo is imported: an align step's camera renders
    assembled = _assemble(args, cell, tasks, kind, log, faults)
    if faults is not None:
        faults.attach(assembled.controller)
        assembled.loop.add_observer(faults)
    if kind == "sim" and getattr(args, "sim_fast", False):
        assembled.loop.run_ahead = True  # a job's motions in look-aheads (RUN_AHEAD_S)
    recorder = None
    if record:
        from cellrunner.record.attach import record_jobs

        recorder = record_jobs(assembled, folder, "." + args.record_format, args.record_max_mb)
    if cell.cell.watch is not None and assembled.watch is None:
        log.warning(
            "not_watched", why="depth images of the arm's cell come with the twin backend only"
        )
    _load_planning_libraries()
    # the planning thread is CPU-bound; hand the GIL over every 1 ms (Python's default is
    # 5 ms) so the PLC threads answer promptly while a job plans
    sys.setswitchinterval(0.001)
    # SIGTERM and Ctrl-C: the job closed with 107 and exit 0 within 2 s, even with a
    # controller that does not answer (see cellrunner.cli.stopping)
    signals = contextlib.ExitStack()
    stopping = signals.enter_context(stop_on_signals(exit_code=0))
    links = _Links(assembled, cell, tasks, http, log)
    try:
        serve(
            assembled,
            stopping.event,
            log,
            stop_reason=lambda: stopping.reason,
            open_links=links.open,
            on_serving=links.serving,
            on_stopped=functools.partial(_on_stopped, args, assembled, recorder),
        )
    finally:
        signals.close()
    return 0


def _assemble(
    args: argparse.Namespace,
    cell: LoadedCell,
    tasks: dict[int, LoadedTask],
    kind: str,
    log: Any,
    faults: ServeFaults | None,
) -> AssembledCell:
    """The cell as ``serve`` runs it: warmed, watched and fed on the twin."""
    return assemble_cell(
        cell,
        tasks,
        kind,
        robot_host=args.robot_host,
        warm=True,  # before READY: the first job is acknowledged as fast as any other
        log=log,
        wait_for_unhold=True,
        feed_parts=True,
        # the twin at the clock's pace, unless a soak asks for its fastest
        realtime=kind == "sim" and not getattr(args, "sim_fast", False),
        eye=True,
        image_source=getattr(args, "image_source", None),
        watched=kind == "sim",
        depth_source=getattr(args, "depth_source", None),
        on_step_start=faults.on_step_start if faults is not None else None,
    )


def _on_stopped(
    args: argparse.Namespace, assembled: AssembledCell, recorder: Collector | None
) -> None:
    """What a stopped ``serve`` closes last: the recorder, the journal's last writes, the map."""
    if recorder is not None:
        recorder.close(timeout_s=0.8)  # within the 2 s a SIGTERM allows
    # the journal's last writes too, so that one that cannot land is still named on the
    # way out, before the grace runs out (a write that can land does within 0.1-0.3 s)
    journal = assembled.journal
    journal.flush_timeout_s = min(journal.flush_timeout_s, JOURNAL_STOP_FLUSH_S)
    if assembled.watch is not None and getattr(args, "save_map", None):
        assembled.watch.map.save(args.save_map)


def _faults(args: argparse.Namespace, kind: str, log: Any) -> ServeFaults | None:
    """``--faults FILE``: the twin's faults at per-job rates (a soak's), or None."""
    path = getattr(args, "faults", None)
    if not path:
        return None
    from pathlib import Path

    from cellrunner.cli.shift import load_rates
    from cellrunner.execution.serve_faults import SERVE_FAULTS, ServeFaults

    if kind != "sim":
        raise UsageError("--faults makes faults happen in the twin: use it with --backend sim")
    # robot_disconnect and plc_disconnect: a soak's kill -9 and PLC outage rehearse those
    rates = load_rates(Path(path), SERVE_FAULTS)
    return ServeFaults(rates, seed=getattr(args, "seed", 0) or 0, log=log)


class _Links:
    """The PLC servers and the status page of one ``serve``: started, logged, closed."""

    def __init__(
        self,
        assembled: AssembledCell,
        cell: LoadedCell,
        tasks: dict[int, LoadedTask],
        http: tuple[str, int] | None,
        log: Any,
    ) -> None:
        self.assembled, self.cell, self.tasks, self.http, self.log = (
            assembled,
            cell,
            tasks,
            http,
            log,
        )
        self.service: PlcService | None = None
        self.status_page: StatusServer | None = None

    def open(self, closers: list[Closer]) -> None:
        service = self.service = _plc_service(self.assembled.controller, self.cell)
        if service is not None:
            closers.append(service.stop)
        if self.http:
            page = self.status_page = _status_page(self.assembled, service, self.http, self.log)

            def close_page() -> None:
                page.stop()
                page.board.close()

            closers.append(close_page)

    def serving(self) -> None:
        service, status_page = self.service, self.status_page
        self.log.info(
            "serving",
            backend=self.assembled.backend_kind,
            tasks={n: t.name for n, t in self.tasks.items()},
            modbus=getattr(service, "modbus_address", None) if service else None,
            http=status_page.url if status_page else None,
        )


def _page_controls(controller: CellController, cell: LoadedCell, log: EventLog) -> Any:
    """The page's Hold, Resume and Clear buttons for the operators of the cell's OPC UA
    users file (the same users and roles); None (a read-only page) without one."""
    opcua = cell.cell.plc.opcua
    if opcua is None or not opcua.users:
        return None
    from cellrunner.plc.users import role_checker
    from cellrunner.web.controls import PageControls

    return PageControls(controller, role_checker(cell.resolve(opcua.users)), log)


def _status_page(
    assembled: AssembledCell,
    service: PlcService | None,
    address: tuple[str, int],
    log: EventLog,
) -> StatusServer:
    """The status page and /metrics on their own thread, reading the journal through
    their own connection; its live 3D view samples the arm as one of the control loop's
    observers (built now: the arm's geometry and the cell's meshes load before READY)."""
    from cellrunner.web.board import StatusBoard
    from cellrunner.web.live import LiveView
    from cellrunner.web.live_feed import LiveFeed
    from cellrunner.web.server import StatusServer, is_loopback

    controller, cell = assembled.controller, assembled.loaded
    feed = LiveFeed()
    live = LiveView(feed, assembled.world, assembled.watch)
    assembled.loop.add_observer(feed)
    host, port = address
    journal = cell_journal(cell)
    board = StatusBoard(
        controller,
        journal,
        cell.cell.cell,
        plc_links=service.links if service is not None else dict,
    ).setup()
    server = StatusServer(board, host, port, live, _page_controls(controller, cell, log))
    try:
        server.start()
    except Exception:  # whatever stopped the page's server, the board is closed, then re-raised
        board.close()
        raise
    if not is_loopback(host):
        log.warning(
            "status_page_not_loopback",
            host=host,
            note="the status page is reachable from the network (read-only)",
        )
    return server


def _plc_service(controller: CellController, cell: LoadedCell) -> PlcService | None:
    plc = cell.cell.plc
    if plc.modbus is None and plc.opcua is None:
        return None
    from cellrunner.plc.service import PlcService

    if plc.opcua and plc.opcua.pki:
        pki = cell.resolve_output(plc.opcua.pki)
    elif is_database_url(cell.cell.journal):
        pki = cell.resolve_output("var/pki")
    else:
        pki = cell.resolve_output(cell.cell.journal).parent / "pki"
    service = PlcService(
        controller, plc, resolve=cell.resolve, pki_dir=pki, cell_name=cell.cell.cell
    )
    service.start()
    modbus = service.modbus
    if modbus is not None:
        link = modbus.link  # the belts the PLC counts: their encoders in its registers 20-29
        controller.read_plc_encoders(lambda: link.encoder_registers)
    return service


def _load_planning_libraries() -> None:
    """Load OMPL and TOPP-RA now, before the PLC link is up: loading them holds Python's
    GIL for tenths of a second, which during the first job would stall every thread of
    the process, the PLC heartbeat among them."""
    import ompl.geometric  # noqa: F401
    import toppra  # noqa: F401
