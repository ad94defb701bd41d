"""Chaos soak: kill -9 ``serve`` at random moments while a PLC runs jobs, then reconcile.

    sudo PYTHONPATH=. python bench/chaos_serve.py [--minutes 30] [--host 127.0.0.160]
                                                  [--disk-full-at 0.4] [--json out.json]

Processes, each its own: ``cellrunner twin`` (the virtual UR controller, up for the whole
run, as a real arm is), ``cellrunner serve --backend ur`` against it (killed with SIGKILL
and started again, over and over), and a PLC (pyModbusTCP) that runs jobs one after
another the way a PLC program does: heartbeat every 100 ms, wait READY (RESET or UNHOLD
when the cell needs it), write id and task, raise JOB_REQ, wait JOB_ACK, wait DONE or
ERROR, drop JOB_REQ. A PLC that loses the cell mid-handshake asks again with the same id
once it is back (SPEC: the same id gets the job's result, never a second run). Every job
id is new (1, 2, 3, ...).

The kills: right after the PLC sees JOB_ACK, right after it sees DONE or ERROR, mid-job,
and at a random moment (each drawn in turn, seeded). The journal lives on a small tmpfs
(root is needed to mount it), which is filled once (at ``--disk-full-at`` of the run)
for 20 s with a kill inside it, so a result is held through a full disk and a restart.

At the end serve is stopped with SIGTERM and the PLC's log is reconciled with the journal:

* accepted: ids the PLC saw acknowledged (JOB_ACK, or a result replayed for its id);
* recorded: those ids found in the journal, each closed (a result or 107);
* lost: accepted but not in the journal (target 0);
* duplicated: ids with more than one journal row (target 0);
* mismatched: ids whose result the PLC read differs from the journal's (target 0).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
CLI = (sys.executable, "-m", "cellrunner.cli.main")
ENV = {**os.environ, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
KILL_MODES = ("after_ack", "after_done", "mid_job", "random")
READY, ACK, BUSY, DONE, ERROR, REJECTED, HELD_BIT, PSTOP, ESTOP, WATCHDOG = (
    1,
    2,
    4,
    8,
    16,
    512,
    32,
    64,
    128,
    256,
)
JOB_REQ, RESET, UNHOLD = 1, 2, 16
#: a PLC heartbeat outage (s): past the cell's heartbeat_timeout (2 s), so its watchdog holds
OUTAGE_S = 3.0
STOPPED, IDLE, ABORTED, HELD = 2, 4, 9, 11

TOUR = """task: tour
steps:
  - move: {to: pallet, offset: [0, 0, -0.15]}
  - move: home
on_protective_stop: {resume: true, max: 3}
"""


# -- the PLC (a child process) --------------------------------------------------------------
def plc_main(
    host: str, port: int, seconds: float, seed: int, outage_rate: float = 0.0, first_id: int = 1
) -> None:
    """Jobs until ``seconds`` have passed; one JSON line per event on stdout, each with the
    job's id and its number ``n`` (1, 2, ...). With ``outage_rate`` (per job) the PLC stops
    its heartbeat for OUTAGE_S once a job is acknowledged (a PLC that drops off the
    network): the cell's watchdog holds it, and the PLC presses UNHOLD once it is back, as
    a PLC program does. The ids start at ``first_id`` and wrap from 65535 to 1, as a PLC's
    16-bit counter does (SPEC 7: register 2)."""
    from pyModbusTCP.client import ModbusClient

    rng = random.Random(seed)
    outages = random.Random(seed + 1)  # its own draws: the jobs' tasks stay the same
    client = ModbusClient(host=host, port=port, timeout=1.0, auto_open=True)
    lock = threading.Lock()
    stop = threading.Event()
    silent_until = [0.0]

    def emit(**event: Any) -> None:
        print(json.dumps({"t": time.time(), **event}), flush=True)

    def raw(tag: str, r: list[int] | None) -> None:  # what the PLC read, for a post-mortem
        if r is not None:
            emit(ev="read", tag=tag, id=job_id, regs=r[:8])

    def beat() -> None:
        value = 0
        while not stop.wait(0.1):
            if time.monotonic() < silent_until[0]:
                continue
            value = (value + 1) & 0xFFFF
            with lock:
                client.write_single_register(0, value)

    def regs() -> list[int] | None:
        with lock:
            r = client.read_holding_registers(100, 14)
        return list(r) if r else None

    def write(addr: int, values: list[int]) -> bool:
        with lock:
            return bool(client.write_multiple_registers(addr, values))

    def poke(bit: int, keep: int) -> None:
        write(1, [keep | bit])
        time.sleep(0.05)
        write(1, [keep])

    def wait(pred: Any, timeout_s: float, keep: int) -> list[int] | None:
        """Registers once ``pred`` holds; None on timeout. Presses RESET/UNHOLD as a PLC
        program does."""
        deadline = time.monotonic() + timeout_s
        last_press = 0.0
        while time.monotonic() < deadline:
            r = regs()
            if r is not None:
                if pred(r):
                    return r
                bits, state = r[1], r[2]
                if time.monotonic() - last_press > 0.5:
                    if state in (STOPPED, ABORTED) or (
                        state == IDLE and bits & PSTOP and not bits & BUSY
                    ):
                        poke(RESET, keep)
                        last_press = time.monotonic()
                    elif state == HELD and not bits & (WATCHDOG | ESTOP):
                        poke(UNHOLD, keep)
                        last_press = time.monotonic()
            time.sleep(0.01)
        return None

    threading.Thread(target=beat, daemon=True).start()
    end_at = time.monotonic() + seconds
    job_id, n = (first_id - 2) % MAX_JOB_ID + 1, 0
    while time.monotonic() < end_at:
        job_id, n = job_id % MAX_JOB_ID + 1, n + 1
        task = 1 if rng.random() < 0.8 else 2
        seen_ack = False
        for _attempt in range(200):  # the same id until its end is read
            if time.monotonic() > end_at + 120:
                break
            if (
                wait(
                    lambda r, j=job_id: r[1] & READY or (r[4] == j and r[1] & (DONE | ERROR)), 60, 0
                )
                is None
            ):
                continue
            if not (write(2, [job_id, task]) and write(1, [0]) and write(1, [JOB_REQ])):
                continue
            r = wait(lambda r, j=job_id: r[1] & (ACK | REJECTED) and r[3] == j, 3.0, JOB_REQ)
            raw("ack", r)
            if r is None:
                continue  # the cell went away: ask again with the same id
            if r[1] & REJECTED:
                emit(ev="reject", id=job_id, n=n, code=r[5])
                write(1, [0])
                if r[5] == 12:
                    time.sleep(0.5)
                    continue  # not ready (a full journal, a restart): the same id later
                break
            if not seen_ack:
                emit(ev="ack", id=job_id, n=n, task=task)
                seen_ack = True
                if outage_rate and outages.random() < outage_rate:
                    silent_until[0] = time.monotonic() + OUTAGE_S
                    emit(ev="outage", id=job_id, n=n)
            # the end, or READY: a restarted cell that no longer runs it (its register
            # image starts with JOB_REQ low)
            r = wait(
                lambda r, j=job_id: (r[1] & (DONE | ERROR) and r[4] == j) or r[1] & READY,
                180,
                JOB_REQ,
            )
            raw("end", r)
            if r is None or not r[1] & (DONE | ERROR):
                continue  # killed mid-job: after the restart, the same id again
            emit(ev="end", id=job_id, n=n, code=r[5], done=bool(r[1] & DONE))
            write(1, [0])
            wait(lambda r: not r[1] & (ACK | DONE | ERROR | REJECTED), 5.0, 0)
            break
    stop.set()
    emit(ev="quit", last_id=job_id)


# -- the chaos (this process) ---------------------------------------------------------------
#: the largest job id (SPEC 7, register 2: 1-65535); the PLC's next one is 1 again
MAX_JOB_ID = 65535


class Chaos:
    def __init__(self, root: Path, host: str, seconds: float, seed: int, disk_at: float) -> None:
        self.root, self.host, self.seconds, self.disk_at = root, host, seconds, disk_at
        self.rng = random.Random(seed)
        self.seed = seed
        self.events: list[dict[str, Any]] = []
        self.new_event = threading.Condition()
        self.kills: Counter[str] = Counter()
        self.serve: subprocess.Popen[bytes] | None = None
        self.restarts = 0
        self.self_exits = 0
        self.serve_lock = threading.RLock()
        self.disk_full_s = 0.0
        self.serve_log = open(root / "serve.log", "ab")  # noqa: SIM115 - kept for the run

    def project(self) -> tuple[Path, int, Path]:
        """The cell (the demo cell, its journal on a tmpfs), its Modbus port, the disk."""
        import socket

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        (self.root / "cells").mkdir()
        (self.root / "tasks").mkdir()
        disk = self.root / "disk"
        disk.mkdir()
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=8m", "tmpfs", str(disk)], check=True)
        text = (REPO / "cells" / "demo_ur5e.yaml").read_text()
        text = text.split("\ntasks:")[0]
        text += (
            "\ntasks: {1: tasks/tour.yaml, 2: tasks/home.yaml}\n"
            f"plc:\n  modbus: {{bind: 127.0.0.1, port: {port}, heartbeat_timeout: 2.0}}\n"
            f"journal: {disk / 'jobs.sqlite'}\n"
        )
        cell = self.root / "cells" / "chaos.yaml"
        cell.write_text(text)
        (self.root / "tasks" / "tour.yaml").write_text(TOUR)
        shutil.copy(REPO / "tasks" / "home.yaml", self.root / "tasks" / "home.yaml")
        return cell, port, disk

    def start_serve(self, cell: Path) -> None:
        self.serve = subprocess.Popen(
            [
                *CLI,
                "--log-format",
                "json",
                "serve",
                str(cell),
                "--backend",
                "ur",
                "--robot-host",
                self.host,
            ],
            cwd=self.root,
            stdout=subprocess.DEVNULL,
            stderr=self.serve_log,
            env=ENV,
        )

    def kill_serve(self, mode: str) -> None:
        with self.serve_lock:
            assert self.serve is not None
            self.serve.send_signal(signal.SIGKILL)
            self.serve.wait(30)
            self.kills[mode] += 1

    def supervise(self, cell: Path, done: threading.Event) -> None:
        """Start serve again when it exits by itself (e.g. it could not reach the twin,
        or its journal's disk was full at start-up)."""
        while not done.wait(1.0):
            with self.serve_lock:
                if self.serve is not None and self.serve.poll() is not None:
                    self.self_exits += 1
                    self.start_serve(cell)

    def read_plc(self, plc: subprocess.Popen[str]) -> None:
        assert plc.stdout is not None
        for line in plc.stdout:
            if line.startswith("{"):
                event = json.loads(line)
                with self.new_event:
                    self.events.append(event)
                    self.new_event.notify_all()

    def wait_event(self, kind: str, timeout_s: float) -> bool:
        """Wait for the next PLC event of ``kind`` (ack, end) after now."""
        with self.new_event:
            start = len(self.events)
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                if any(e["ev"] == kind for e in self.events[start:]):
                    return True
                self.new_event.wait(max(0.0, deadline - time.monotonic()))
        return False

    def run(self) -> dict[str, Any]:
        cell, port, disk = self.project()
        twin = subprocess.Popen(
            [*CLI, "twin", str(cell), "--host", self.host],
            cwd=self.root,
            stdout=subprocess.DEVNULL,
            stderr=open(self.root / "twin.log", "wb"),  # noqa: SIM115
            env=ENV,
        )
        time.sleep(8.0)  # the twin builds its model and listens
        self.start_serve(cell)
        plc = subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--plc",
                "127.0.0.1",
                str(port),
                str(self.seconds),
                str(self.seed),
            ],
            stdout=subprocess.PIPE,
            text=True,
            env=ENV,
        )
        threading.Thread(target=self.read_plc, args=(plc,), daemon=True).start()
        supervising = threading.Event()
        threading.Thread(target=self.supervise, args=(cell, supervising), daemon=True).start()
        t0 = time.monotonic()
        disk_done = False
        try:
            while plc.poll() is None and time.monotonic() - t0 < self.seconds:
                if not disk_done and time.monotonic() - t0 > self.disk_at * self.seconds:
                    self.disk_full_episode(disk, cell)
                    disk_done = True
                    continue
                mode = KILL_MODES[sum(self.kills.values()) % len(KILL_MODES)]
                if mode == "after_ack":
                    hit = self.wait_event("ack", 120)
                    time.sleep(self.rng.uniform(0.0, 0.03))
                elif mode == "after_done":
                    hit = self.wait_event("end", 120)
                    time.sleep(self.rng.uniform(0.0, 0.03))
                elif mode == "mid_job":
                    hit = self.wait_event("ack", 120)
                    time.sleep(self.rng.uniform(0.2, 3.0))
                else:
                    hit = True
                    time.sleep(self.rng.uniform(1.0, 20.0))
                if not hit or time.monotonic() - t0 > self.seconds:
                    continue
                with self.serve_lock:
                    self.kill_serve(mode)
                    time.sleep(self.rng.uniform(0.0, 1.0))
                    self.start_serve(cell)
                    self.restarts += 1
                self.wait_event("end", 90)  # let it run a job before the next kill
        finally:
            plc.wait(timeout=400)
            supervising.set()
            if self.serve is not None:
                self.serve.send_signal(signal.SIGTERM)
                try:
                    self.serve.wait(60)
                except subprocess.TimeoutExpired:
                    self.serve.kill()
            twin.terminate()
            twin.wait(60)
        shutil.copy(disk / "jobs.sqlite", self.root / "jobs.sqlite")  # kept for a post-mortem
        with open(self.root / "plc.jsonl", "w") as log:
            log.writelines(json.dumps(e) + "\n" for e in self.events)
        subprocess.run(["umount", "-l", str(disk)], check=False)
        return self.reconcile(self.root / "jobs.sqlite")

    def disk_full_episode(self, disk: Path, cell: Path) -> None:
        """Fill the journal's disk for 20 s, with a kill and restart inside."""
        filler = disk / "filler"
        t = time.monotonic()
        with open(filler, "wb") as file:
            try:
                while True:
                    file.write(b"\0" * 65536)
                    file.flush()
            except OSError:
                pass
        self.wait_event("ack", 30)
        time.sleep(self.rng.uniform(0.5, 5.0))  # a job under way, its end held
        with self.serve_lock:
            self.kill_serve("disk_full")
            self.start_serve(cell)
            self.restarts += 1
        time.sleep(max(0.0, 20.0 - (time.monotonic() - t)))
        filler.unlink()
        self.disk_full_s = time.monotonic() - t

    def reconcile(self, journal_path: Path) -> dict[str, Any]:
        """The PLC's jobs against the journal's rows. A job is its number ``n``; its id
        comes round again every 65535 jobs, so the k-th job the PLC ran under an id is the
        k-th row the journal has for that id (in the order written)."""
        db = sqlite3.connect(journal_path)
        rows = db.execute(
            "SELECT client_job_id, result_code, ended_at FROM jobs WHERE source = 'modbus' "
            "ORDER BY rowid"
        ).fetchall()
        db.close()
        rows_of: dict[int, list[tuple[Any, ...]]] = {}
        for r in rows:
            rows_of.setdefault(int(r[0]), []).append(r)
        unfinished = [int(r[0]) for r in rows if r[2] is None]
        id_of = {e["n"]: e["id"] for e in self.events if e["ev"] in ("ack", "end")}
        ends = {e["n"]: e["code"] for e in self.events if e["ev"] == "end"}
        accepted = sorted(id_of)
        jobs_of: dict[int, list[int]] = {}
        for n in accepted:
            jobs_of.setdefault(id_of[n], []).append(n)
        row_of = {
            n: rows_of[i][k]
            for i, ns in jobs_of.items()
            for k, n in enumerate(ns)
            if k < len(rows_of.get(i, []))
        }
        lost = [n for n in accepted if n not in row_of]
        # more rows than the PLC's jobs under the id (one row for a job it never saw
        # acknowledged, the last when the soak ended, is not a job run twice)
        duplicated = sorted(
            i for i, rs in rows_of.items() if len(rs) > max(1, len(jobs_of.get(i, [])))
        )
        mismatched = sorted(n for n, code in ends.items() if n in row_of and row_of[n][1] != code)
        codes = Counter(row_of[n][1] for n in accepted if n in row_of)
        return {
            "minutes": round(self.seconds / 60, 1),
            "kills": dict(self.kills),
            "restarts": self.restarts,
            "serve_exits_restarted": self.self_exits,
            "disk_full_s": round(self.disk_full_s, 1),
            "accepted": len(accepted),
            "recorded": len(row_of),
            "journal_rows": len(rows),
            "lost": lost,
            "duplicated": duplicated,
            "mismatched": mismatched,
            "unfinished_rows": unfinished,
            "results_read_by_plc": len(ends),
            "closed_107": codes.get(107, 0),
            "codes": {str(k): v for k, v in sorted(codes.items())},
            "rejects": dict(Counter(e["code"] for e in self.events if e["ev"] == "reject")),
        }


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--plc":
        plc_main(
            argv[1],
            int(argv[2]),
            float(argv[3]),
            int(argv[4]),
            float(argv[5]) if argv[5:] else 0.0,
            int(argv[6]) if argv[6:] else 1,
        )
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--host", default="127.0.0.160", help="the twin's address")
    ap.add_argument("--seed", type=int, default=28)
    ap.add_argument("--disk-full-at", type=float, default=0.4, help="fraction of the run")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    if os.geteuid() != 0:
        sys.stderr.write("chaos_serve: needs root (the journal's disk is a tmpfs it mounts)\n")
        return 2
    root = Path(tempfile.mkdtemp(prefix="chaos-"))
    report = Chaos(root, args.host, args.minutes * 60, args.seed, args.disk_full_at).run()
    report["work_dir"] = str(root)
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    ok = not (report["lost"] or report["duplicated"] or report["mismatched"])
    ok = ok and not report["unfinished_rows"] and report["accepted"] == report["recorded"]
    print(
        f"chaos soak {report['minutes']} min: {sum(report['kills'].values())} kill -9s "
        f"{report['kills']}, accepted {report['accepted']} = recorded {report['recorded']}, "
        f"lost {len(report['lost'])}, duplicated {len(report['duplicated'])}, "
        f"mismatched {len(report['mismatched'])}: {'OK' if ok else 'FAILED'}"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
