"""A week of production without a lost job, measured (issue 37).

    PYTHONPATH=. python bench/soak_week.py [--hours 168] [--kill-every 300] [--seed 37]
                                           [--faults protective_stop=0.02,estop=0.005]
                                           [--plc-outage-rate 0.002] [--json out.json]

``cellrunner serve --backend sim --sim-fast`` (the twin at its fastest, not at the clock's
pace) runs the jobs of an independent PLC (its own process: pyModbusTCP, heartbeat every
100 ms, the handshake of SPEC 7; the PLC of bench/chaos_serve.py) for the equivalent of
``--hours`` of the demo's cycle (476 jobs an hour: 80,000 jobs a week). ``serve`` is
killed with SIGKILL every ``--kill-every`` jobs, at a moment drawn in turn (right after
an acknowledgement, right after a result, mid-job, at random) and started again; the PLC
asks again with the same id when the cell went away mid-handshake.

Halfway through each life of ``serve`` (at the same job count after each start), its
resident memory, open files and threads are read from /proc. At the end serve is stopped
with SIGTERM and the PLC's log is reconciled with the journal: 0 lost, 0 run twice, 0
results differing from the journal's, every row closed; memory within 10 % from the
first sample to the last, no growth in open files or threads.

Faults besides the kills: ``--faults`` gives ``serve --faults`` its per-job rates (the
twin makes them happen: protective stops, which the task resumes; e-stops, released by
the operator 2 s later, after which the PLC's RESET recovers the cell; grip misses and
slips where the task grips), and ``--plc-outage-rate`` has the PLC drop its heartbeat for
3 s after an acknowledgement (the cell's watchdog holds it; the PLC presses UNHOLD once
back). A job a fault made fail is a result the PLC reads, not a lost job.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.chaos_serve import CLI, ENV, KILL_MODES, TOUR, Chaos

#: the demo's jobs in one hour (a 7.6 s cycle): 80,000 jobs in 168 hours
JOBS_PER_HOUR = 476
#: a PLC that outlives the run (it is stopped once the jobs are done)
PLC_SECONDS = 10 * 24 * 3600.0


class Soak(Chaos):
    """The chaos soak's PLC, serve and reconcile, with the twin in serve at its fastest,
    a journal on the ordinary disk, kills every ``kill_every`` jobs and /proc samples."""

    def __init__(
        self,
        root: Path,
        jobs: int,
        kill_every: int,
        seed: int,
        faults: dict[str, float] | None = None,
        outage_rate: float = 0.0,
    ) -> None:
        super().__init__(root, "", 0.0, seed, 0.0)
        self.jobs, self.kill_every = jobs, kill_every
        self.faults, self.outage_rate = faults or {}, outage_rate
        self.max_wall_s = float("inf")  # then the jobs done so far are reconciled
        self.first_id = 1  # the PLC's first job id (it wraps after 65535)
        self.samples: list[dict[str, Any]] = []
        self.ends = 0

    def project(self) -> tuple[Path, int, Path]:
        import shutil
        import socket

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        (self.root / "cells").mkdir()
        (self.root / "tasks").mkdir()
        text = (Path(__file__).resolve().parent.parent / "cells" / "demo_ur5e.yaml").read_text()
        text = text.split("\ntasks:")[0]
        text += (
            "\ntasks: {1: tasks/tour.yaml, 2: tasks/home.yaml}\n"
            f"plc:\n  modbus: {{bind: 127.0.0.1, port: {port}, heartbeat_timeout: 2.0}}\n"
            f"journal: {self.root / 'jobs.sqlite'}\n"
        )
        cell = self.root / "cells" / "soak.yaml"
        cell.write_text(text)
        (self.root / "tasks" / "tour.yaml").write_text(TOUR)
        repo = Path(__file__).resolve().parent.parent
        shutil.copy(repo / "tasks" / "home.yaml", self.root / "tasks" / "home.yaml")
        if self.faults:
            (self.root / "faults.yaml").write_text(json.dumps(self.faults) + "\n")
        return cell, port, self.root

    def start_serve(self, cell: Path) -> None:
        self.serve = subprocess.Popen(
            [
                *CLI,
                "--log-format",
                "json",
                "serve",
                str(cell),
                "--backend",
                "sim",
                "--sim-fast",
                *(
                    ["--faults", "faults.yaml", "--seed", str(self.seed + self.restarts)]
                    if self.faults
                    else []
                ),
            ],
            cwd=self.root,
            stdout=subprocess.DEVNULL,
            stderr=self.serve_log,
            env=ENV,
        )
        self.started_at_end = self.ends

    def read_plc(self, plc: subprocess.Popen[str]) -> None:
        assert plc.stdout is not None
        for line in plc.stdout:
            event = json.loads(line)
            if event["ev"] == "read":
                continue
            with self.new_event:
                self.events.append(event)
                if event["ev"] == "end":
                    self.ends += 1
                self.new_event.notify_all()

    def sample(self) -> None:
        """The serve process's resident memory (MiB), open files and threads."""
        with self.serve_lock:
            pid = self.serve.pid if self.serve is not None else None
        if pid is None:
            return
        try:
            status = Path(f"/proc/{pid}/status").read_text()
            fds = len(os.listdir(f"/proc/{pid}/fd"))
        except OSError:
            return
        fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
        self.samples.append(
            {
                "job": self.ends,
                "rss_mib": round(int(fields["VmRSS"].split()[0]) / 1024, 1),
                "open_files": fds,
                "threads": int(fields["Threads"]),
            }
        )

    def run(self) -> dict[str, Any]:
        cell, port, _ = self.project()
        self.start_serve(cell)
        plc = subprocess.Popen(
            [
                sys.executable,
                str(Path(__file__).resolve().parent / "chaos_serve.py"),
                "--plc",
                "127.0.0.1",
                str(port),
                str(PLC_SECONDS),
                str(self.seed),
                str(self.outage_rate),
                str(self.first_id),
            ],
            stdout=subprocess.PIPE,
            text=True,
            env=ENV,
        )
        threading.Thread(target=self.read_plc, args=(plc,), daemon=True).start()
        supervising = threading.Event()
        threading.Thread(target=self.supervise, args=(cell, supervising), daemon=True).start()
        t0 = time.monotonic()
        sampled_life = -1
        try:
            while (
                self.ends < self.jobs
                and plc.poll() is None
                and time.monotonic() - t0 < self.max_wall_s
            ):
                life = self.restarts
                since = self.ends - self.started_at_end
                if life != sampled_life and since >= max(1, self.kill_every // 2):
                    self.sample()
                    sampled_life = life
                if self.kill_every and since >= self.kill_every:
                    mode = KILL_MODES[sum(self.kills.values()) % len(KILL_MODES)]
                    if mode == "after_ack":
                        self.wait_event("ack", 60)
                        time.sleep(self.rng.uniform(0.0, 0.03))
                    elif mode == "after_done":
                        self.wait_event("end", 60)
                        time.sleep(self.rng.uniform(0.0, 0.03))
                    elif mode == "mid_job":
                        self.wait_event("ack", 60)
                        time.sleep(self.rng.uniform(0.05, 0.3))
                    else:
                        time.sleep(self.rng.uniform(0.0, 1.0))
                    with self.serve_lock:
                        self.kill_serve(mode)
                        self.start_serve(cell)
                        self.restarts += 1
                    continue
                with self.new_event:
                    self.new_event.wait(1.0)
        finally:
            self.sample()
            plc.send_signal(signal.SIGTERM)
            plc.wait(30)
            supervising.set()
            if self.serve is not None:
                self.serve.send_signal(signal.SIGTERM)
                try:
                    self.serve.wait(60)
                except subprocess.TimeoutExpired:
                    self.serve.kill()
        wall_s = time.monotonic() - t0
        report = self.reconcile(self.root / "jobs.sqlite")
        report.pop("minutes", None)
        report.pop("disk_full_s", None)
        report["jobs_target"] = self.jobs
        report["hours_of_demo_cycle"] = round(self.ends / JOBS_PER_HOUR, 2)
        report["wall_s"] = round(wall_s, 1)
        report["faults_struck"] = faults_struck(self.root / "serve.log")
        report["plc_outages"] = sum(1 for e in self.events if e["ev"] == "outage")
        report["samples"] = self.samples
        report["resources"] = resources(self.samples)
        return report


def faults_struck(serve_log: Path) -> dict[str, int]:
    """The twin's faults that struck, by name, over every life of serve (its JSON log)."""
    from collections import Counter

    struck: Counter[str] = Counter()
    for line in serve_log.read_text(errors="replace").splitlines():
        if '"fault_injected"' in line:
            try:
                struck[json.loads(line)["fault"]] += 1
            except (ValueError, KeyError):
                continue
    return dict(struck)


def resources(samples: list[dict[str, Any]]) -> dict[str, Any]:
    """First against last sample taken at the same point of a serve's life."""
    lives = samples[:-1] if len(samples) > 2 else samples  # the last is taken at the end
    if len(lives) < 2:
        return {"compared": False}
    first, last = lives[0], lives[-1]
    return {
        "compared": True,
        "rss_growth": round(last["rss_mib"] / first["rss_mib"] - 1.0, 4),
        "open_files": [first["open_files"], last["open_files"]],
        "threads": [first["threads"], last["threads"]],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hours", type=float, default=168.0, help="of the demo's cycle (476 jobs/h)")
    ap.add_argument("--kill-every", type=int, default=300, help="jobs between kill -9s (0: none)")
    ap.add_argument("--seed", type=int, default=37)
    ap.add_argument(
        "--faults",
        default="",
        help="the twin's faults per job, e.g. protective_stop=0.02,estop=0.005 (serve --faults)",
    )
    ap.add_argument(
        "--plc-outage-rate", type=float, default=0.0, help="per job: the PLC's heartbeat stops 3 s"
    )
    ap.add_argument(
        "--first-id",
        type=int,
        default=1,
        help="the PLC's first job id (1-65535; ids wrap after 65535 as a PLC's counter does)",
    )
    ap.add_argument(
        "--max-wall-s",
        type=float,
        default=float("inf"),
        help="stop after this much wall time and reconcile the jobs done (a bounded run)",
    )
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    faults = {
        name: float(rate)
        for name, _, rate in (item.partition("=") for item in args.faults.split(",") if item)
    }
    random.seed(args.seed)
    root = Path(tempfile.mkdtemp(prefix="soak-week-"))
    jobs = max(1, round(args.hours * JOBS_PER_HOUR))
    soak = Soak(root, jobs, args.kill_every, args.seed, faults, args.plc_outage_rate)
    soak.max_wall_s = args.max_wall_s
    soak.first_id = args.first_id
    report = soak.run()
    report["work_dir"] = str(root)
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    res = report["resources"]
    ok = not (report["lost"] or report["duplicated"] or report["mismatched"])
    ok = ok and not report["unfinished_rows"] and report["accepted"] == report["recorded"]
    if res["compared"]:
        ok = ok and abs(res["rss_growth"]) <= 0.10
        ok = ok and res["open_files"][1] <= res["open_files"][0]
        ok = ok and res["threads"][1] <= res["threads"][0]
    print(
        f"soak of {report['hours_of_demo_cycle']} h of the demo's cycle ({report['accepted']} jobs) "
        f"in {report['wall_s']} s: {sum(report['kills'].values())} kill -9s {report['kills']}, "
        f"faults {report['faults_struck']}, PLC outages {report['plc_outages']}, "
        f"codes {report['codes']}, "
        f"lost {len(report['lost'])}, duplicated {len(report['duplicated'])}, "
        f"mismatched {len(report['mismatched'])}, resources {res}: {'OK' if ok else 'FAILED'}"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
