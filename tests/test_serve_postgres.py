"""Two `cellrunner serve` processes (two cells, twin backends, Modbus PLCs) share one
PostgreSQL journal through a database crash and restart: every job a PLC saw
acknowledged is journaled once with the result the PLC saw, none is lost or duplicated,
a job refused while the database was away left nothing behind; a cell killed mid-job
closes its own job with 107 at restart and touches no other cell's."""

from __future__ import annotations

import csv
import faulthandler
import io
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from pyModbusTCP.client import ModbusClient

from tests.conftest import ROOT
from tests.execution.pg_server import PgServer, free_port
from tests.rig import CELL, TASK, start_serve

HOST = "127.0.0.143"
READY, JOB_ACK, BUSY, DONE, ERROR, REJECTED = 1, 2, 4, 8, 16, 512
IDLE = 4  # PackML StateCurrent
#: the first runs through the crash (its result held until the database is back), then one more
JOBS_PER_CELL = 2


class Plc(threading.Thread):
    """One cell's PLC: asks for jobs one after another until ``n_ok`` were acknowledged
    and done; a refused request is asked again later under a new job id."""

    def __init__(self, port: int, first_id: int, n_ok: int = JOBS_PER_CELL):
        super().__init__(daemon=True)
        self.client = ModbusClient(host=HOST, port=port, timeout=2.0, auto_open=True)
        self.next_id, self.n_ok = first_id, n_ok
        self.beat = 0
        self.accepted: dict[int, int] = {}  # PLC job id -> result code seen
        self.refused: dict[int, int] = {}  # PLC job id -> reject code
        self.running = threading.Event()  # set while an acknowledged job is under way
        self.error: BaseException | None = None

    def poll(self) -> list[int]:
        self.beat = (self.beat + 1) % 65536
        self.client.write_single_register(0, self.beat)
        regs = self.client.read_holding_registers(100, 14)
        return regs or [0] * 14

    def until(self, test, timeout_s: float) -> list[int]:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            regs = self.poll()
            if test(regs[1]):
                return regs
            time.sleep(0.05)
        raise AssertionError(f"PLC timed out; status {self.poll()}")

    def run(self) -> None:
        try:
            deadline = time.monotonic() + 240
            while sum(code == 0 for code in self.accepted.values()) < self.n_ok:
                assert time.monotonic() < deadline, (self.accepted, self.refused)
                self.until(lambda st: st & READY, 60)
                job_id, self.next_id = self.next_id, self.next_id + 1
                self.client.write_multiple_registers(2, [job_id, 1])
                self.client.write_single_register(1, 1)
                regs = self.until(lambda st: st & (JOB_ACK | REJECTED), 10)
                if regs[1] & REJECTED:
                    self.refused[job_id] = regs[5]
                else:
                    self.running.set()
                    regs = self.until(lambda st: st & (DONE | ERROR), 120)
                    assert regs[4] == job_id, regs
                    self.accepted[job_id] = regs[5]
                    self.running.clear()
                self.client.write_single_register(1, 0)
                self.until(lambda st: not st & (JOB_ACK | DONE | ERROR | REJECTED), 10)
                if regs[1] & REJECTED:
                    time.sleep(0.5)
        except BaseException as exc:  # reported by the test
            self.error = exc


def write_cell(root: Path, name: str, port: int, journal: str) -> Path:
    folder = root / name
    (folder / "cells").mkdir(parents=True)
    (folder / "tasks").mkdir()
    (folder / "tasks" / "t.yaml").write_text(TASK)
    path = folder / "cells" / "c.yaml"
    path.write_text(
        CELL.replace("cell: dryrun-cell", f"cell: {name}") + "tasks: {1: tasks/t.yaml}\n"
        f"plc:\n  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 3.0}}\njournal: {journal}\n"
    )
    return path


def stop(proc: subprocess.Popen) -> str:
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-3000:]
    return err


def wait_up(plc: Plc, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + 120
    while not plc.client.read_holding_registers(100, 14):
        assert proc.poll() is None, proc.communicate()[1][-3000:]
        assert time.monotonic() < deadline, "serve did not come up"
        time.sleep(0.2)


def test_two_cells_share_one_postgres_journal_through_a_database_restart(tmp_path):
    faulthandler.dump_traceback_later(
        420, exit=True
    )  # two real-time twins: a longer bound than the default
    with PgServer(HOST) as pg:
        ports = {"cell-a": free_port(HOST), "cell-b": free_port(HOST)}
        cells = {name: write_cell(tmp_path, name, port, pg.url) for name, port in ports.items()}
        procs = {name: start_serve(path) for name, path in cells.items()}
        try:
            plcs = {"cell-a": Plc(ports["cell-a"], 100), "cell-b": Plc(ports["cell-b"], 200)}
            for name, plc in plcs.items():
                wait_up(plc, procs[name])
            for plc in plcs.values():
                plc.start()
            # crash the database while both cells run their first job (its start and first
            # steps already committed, the rest written after recovery)
            deadline = time.monotonic() + 180
            while not all(p.running.is_set() for p in plcs.values()):
                assert time.monotonic() < deadline and all(p.is_alive() for p in plcs.values()), [
                    (p.accepted, p.error) for p in plcs.values()
                ]
                time.sleep(0.05)
            time.sleep(1.0)
            # down past the end of a job: its result is held (BUSY in Idle, no DONE) until
            # the database has it, so no PLC is told a result the journal does not hold
            pg.stop("immediate")
            told = {name: dict(p.accepted) for name, p in plcs.items()}
            observers = {n: ModbusClient(host=HOST, port=p, timeout=2.0) for n, p in ports.items()}
            held: set[str] = set()
            deadline = time.monotonic() + 60
            while not held:
                for name, observer in observers.items():
                    regs = observer.read_holding_registers(100, 14) or [0] * 14
                    if regs[1] & BUSY and regs[2] == IDLE and not regs[1] & (DONE | ERROR):
                        held.add(name)
                assert time.monotonic() < deadline and all(p.is_alive() for p in plcs.values()), [
                    (p.accepted, p.error) for p in plcs.values()
                ]
                time.sleep(0.05)
            time.sleep(1.0)
            assert {name: dict(p.accepted) for name, p in plcs.items()} == told
            pg.start()
            for plc in plcs.values():
                plc.join(300)
                assert plc.error is None, plc.error
            # cell-a is killed mid-job: its restart closes that job with 107, cell-b's rows stay
            plc_a = plcs["cell-a"]
            plc_a.until(lambda st: st & READY, 30)
            plc_a.client.write_multiple_registers(2, [150, 1])
            plc_a.client.write_single_register(1, 1)
            plc_a.until(lambda st: st & BUSY, 10)
            time.sleep(1.0)
            procs["cell-a"].kill()
            procs["cell-a"].communicate(timeout=30)
            procs["cell-a"] = start_serve(cells["cell-a"])
            wait_up(plc_a, procs["cell-a"])
            regs = plc_a.poll()
            assert (regs[4], regs[5]) == (150, 107), regs
            plc_a.client.write_single_register(1, 0)
        finally:
            errs = {name: stop(proc) for name, proc in procs.items() if proc.poll() is None}
        assert all("journal:" not in err for err in errs.values()), (
            errs
        )  # no write left undelivered

        rows = pg.sql(
            "SELECT cell, client_job_id, result_code, job_id FROM cellrunner_jobs ORDER BY seq"
        )
        for name, plc in plcs.items():
            mine = [(int(r[1]), r[2]) for r in rows if r[0] == name]
            expected = {**plc.accepted, **({150: 107} if name == "cell-a" else {})}
            assert sorted(mine) == sorted(expected.items()), (name, mine, plc.accepted, plc.refused)
            assert not set(plc.refused) & {i for i, _ in mine}  # refused jobs left nothing behind
            assert set(plc.refused.values()) <= {12}, plc.refused  # 12: not ready (journal away)
        assert held  # the outage was seen: a result held until the database was back
        # every job has all its step transitions, once: the same sequence for every OK job
        step_rows = pg.sql(
            "SELECT s.job_id, s.step_index, s.status FROM cellrunner_steps s "
            "JOIN cellrunner_jobs j USING (job_id) WHERE j.result_code = 0 ORDER BY s.job_id, s.seq"
        )
        per_job: dict[str, list] = {}
        for job_id, index, status in step_rows:
            per_job.setdefault(job_id, []).append((index, status))
        sequences = {tuple(v) for v in per_job.values()}
        assert len(per_job) == 2 * JOBS_PER_CELL and len(sequences) == 1, per_job
        assert next(iter(sequences))[-1][1] == "ok" and len(next(iter(sequences))) >= 20

        out = subprocess.run(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "jobs",
                str(cells["cell-b"]),
                "--all-cells",
                "--csv",
                "--last",
                "50",
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert out.returncode == 0, out.stderr
        listed = list(csv.DictReader(io.StringIO(out.stdout)))
        assert sorted((r["cell"], r["job_id"]) for r in listed) == sorted(
            (r[0], r[3]) for r in rows
        )
