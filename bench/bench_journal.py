"""The journal's cost on the paths that matter, SQLite (the default) vs PostgreSQL (a
throwaway local cluster, as the tests start it), measured in the same run:

* ``begin_job``: the write JOB_ACK waits for (durable on return);
* ``step``: what the control thread pays per step transition (SQLite commits it;
  PostgreSQL queues it to the writer thread);
* ``drain``: the time until a job's step and end writes are all committed.

Both commit durably (SQLite WAL with synchronous=FULL; PostgreSQL with fsync on).

Run from the repository root (as root, PostgreSQL runs as the postgres user)::

    PYTHONPATH=. python bench/bench_journal.py [--jobs 300]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from cellrunner.execution.journal import SqliteJournal
from cellrunner.execution.journal_postgres import PostgresJournal
from cellrunner.model.codes import ResultCode
from tests.execution.pg_server import PgServer

STEPS_PER_JOB = 24  # the demo pick-and-place: 12 expanded steps, running + ok each


def measure(journal, n_jobs: int) -> dict[str, list[float]]:
    begin, step, drain = [], [], []
    for j in range(n_jobs):
        job_id = f"bench{j:06d}"
        t0 = time.perf_counter()
        journal.begin_job(job_id, "bench-cell", "pick_place", {"slot": j % 12}, "modbus", str(j))
        begin.append(time.perf_counter() - t0)
        for i in range(STEPS_PER_JOB):
            t0 = time.perf_counter()
            journal.step(job_id, i // 2 + 1, "move", "home", "ok" if i % 2 else "running", 1)
            step.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        journal.end_job(job_id, ResultCode.OK, 6.5, 0)
        if isinstance(journal, PostgresJournal):
            journal._drain()  # until every write of the job is committed
        drain.append(time.perf_counter() - t0)
    return {"begin_job": begin, "step (caller)": step, "end + drain": drain}


def pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] * 1e3


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--jobs", type=int, default=300)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sqlite = SqliteJournal(Path(tmp) / "jobs.sqlite", "bench-cell").open()
        results = {"sqlite": measure(sqlite, args.jobs)}
        sqlite.close()
    with PgServer("127.0.0.144", durable=True) as pg:  # fsync on, as SQLite's synchronous=FULL
        postgres = PostgresJournal(pg.url, "bench-cell").open()
        results["postgresql"] = measure(postgres, args.jobs)
        postgres.close()
    print(f"journal, {args.jobs} jobs x {STEPS_PER_JOB} step writes (ms)")
    print(f"{'path':<16}{'backend':<12}{'p50':>8}{'p99':>8}{'max':>8}{'pg/sqlite p50':>15}")
    for path in results["sqlite"]:
        base = statistics.median(results["sqlite"][path])
        for backend, series in results.items():
            values = series[path]
            ratio = statistics.median(values) / base if base else float("nan")
            print(
                f"{path:<16}{backend:<12}{pct(values, 0.5):8.3f}{pct(values, 0.99):8.3f}{max(values) * 1e3:8.2f}"
                f"{ratio:15.2f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
