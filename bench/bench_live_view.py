"""The PLC link with the status page's live 3D view open: the cell's Modbus heartbeat gap
with 0 and with 5 open pages, while jobs run.

    PYTHONPATH=. python bench/bench_live_view.py [--seconds 30] [--pages 5] [--rounds 2]
                                                 [--chromium] [--json out.json]

Each round starts ``cellrunner serve --backend sim --http`` (the test rig's pick-and-place
cell, in its own process), and a PLC in this process (pyModbusTCP) that moves its heartbeat
every 100 ms, runs jobs back to back and reads the cell's registers every 5 ms: the gap is
the time between two changes of the cell's heartbeat (register 100, which the cell moves
every 50 ms; SPEC 7: at most 200 ms). Rounds alternate 0 pages and ``--pages`` pages.

A page is, by default, what the page asks of ``serve``: the live stream (server-sent
events, one state per sample), ``/status.json`` every 0.5 s and ``/live/job.json`` at each
new job, from a separate process (so the readers' own work does not count against the
cell). With ``--chromium`` the pages are tabs of one real headless Chromium drawing the 3D
view (WebGL in software: on a small machine that is the browser's CPU taken from the cell,
not the cell's own cost).

Prints, per number of pages: the heartbeat gap median, p99 and max (ms), the jobs finished,
the states the pages received per second; and the ratios of the medians and p99s.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

HOST = "127.0.0.171"
READY, ACK, DONE, ERROR = 1, 2, 8, 16


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind((HOST, 0))
        return int(s.getsockname()[1])


def write_cell(root: Path, modbus_port: int) -> Path:
    from tests.rig import CELL, TASK

    (root / "cells").mkdir(parents=True)
    (root / "tasks").mkdir()
    (root / "tasks" / "t.yaml").write_text(TASK)
    cell = root / "cells" / "c.yaml"
    cell.write_text(
        CELL + "tasks: {1: tasks/t.yaml}\n"
        f"plc:\n  modbus: {{bind: {HOST}, port: {modbus_port}, heartbeat_timeout: 2.0}}\n"
        f"journal: {root}/jobs.sqlite\n"
    )
    return cell


# -- the pages (a child process) ----------------------------------------------------------
def pages_main(url: str, n: int, seconds: float) -> None:
    """``n`` pages' requests for ``seconds``; prints the states received per second."""
    received = [0] * n
    stop = threading.Event()

    def page(i: int) -> None:
        job = ""
        next_status = 0.0
        with urllib.request.urlopen(url + "live/scene.json", timeout=10) as res:
            res.read()
        with urllib.request.urlopen(url + "live/stream", timeout=10) as stream:
            while not stop.is_set():
                line = stream.readline()
                if not line:
                    return
                if not line.startswith(b"data: "):
                    continue
                received[i] += 1
                state = json.loads(line[6:])
                if state.get("job_id") and state["job_id"] != job:
                    job = state["job_id"]
                    with urllib.request.urlopen(url + "live/job.json", timeout=10) as res:
                        res.read()
                if time.monotonic() > next_status:
                    next_status = time.monotonic() + 0.5
                    with urllib.request.urlopen(url + "status.json", timeout=10) as res:
                        res.read()

    threads = [threading.Thread(target=page, args=(i,), daemon=True) for i in range(n)]
    for t in threads:
        t.start()
    time.sleep(seconds)
    stop.set()
    print(json.dumps({"states_per_s": sum(received) / seconds / max(n, 1)}), flush=True)


def chromium_pages(url: str, n: int, profile: Path) -> subprocess.Popen[bytes]:
    """One headless Chromium showing ``url`` in ``n`` tabs (WebGL on SwiftShader)."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        raise SystemExit("--chromium: chromium is not installed (scripts/system-packages)")
    flags = [
        "--headless",
        "--no-sandbox",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--remote-debugging-address=127.0.0.1",
        "--remote-debugging-port=0",
        f"--user-data-dir={profile}",
        "--window-size=1280,900",
    ]
    proc = subprocess.Popen(
        [exe, *flags, url], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    marker = profile / "DevToolsActivePort"
    deadline = time.monotonic() + 30
    while not (marker.exists() and marker.read_text().split("\n")[0].isdigit()):
        if time.monotonic() > deadline or proc.poll() is not None:
            raise SystemExit("chromium did not start")
        time.sleep(0.1)
    port = marker.read_text().split("\n")[0]
    for _ in range(n - 1):
        request = urllib.request.Request(f"http://127.0.0.1:{port}/json/new?{url}", method="PUT")
        urllib.request.urlopen(request, timeout=10).read()
    return proc


# -- one round ------------------------------------------------------------------------------
def run_round(pages: int, seconds: float, chromium: bool) -> dict[str, Any]:
    from pyModbusTCP.client import ModbusClient

    root = Path(tempfile.mkdtemp(prefix="cellrunner-live-bench-"))
    modbus_port, http_port = free_port(), free_port()
    cell = write_cell(root, modbus_port)
    env = {
        **os.environ,
        "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"),
        "PYTHONPATH": str(REPO),
    }
    serve = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.cli.main", "serve", str(cell), "--backend", "sim",
         "--http", f"{HOST}:{http_port}"],
        cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    url = f"http://{HOST}:{http_port}/"
    plc = ModbusClient(host=HOST, port=modbus_port, timeout=2.0, auto_open=True)
    readers: subprocess.Popen[str] | subprocess.Popen[bytes] | None = None
    try:
        deadline = time.monotonic() + 120
        beat = 0
        while not plc.read_holding_registers(100, 14):
            if serve.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"serve did not come up: {serve.stderr.read()[-2000:]!r}")
            time.sleep(0.2)
        while True:  # the page too (it starts after the PLC link)
            try:
                urllib.request.urlopen(url + "live/state.json", timeout=2).read()
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        if pages and chromium:
            readers = chromium_pages(url, pages, root / "chromium")
        elif pages:
            readers = subprocess.Popen(
                [sys.executable, __file__, "--pages-of", url, "--pages", str(pages),
                 "--seconds", str(seconds + 5)],
                env=env, stdout=subprocess.PIPE, text=True,
            )  # fmt: skip
        time.sleep(2.0)  # the pages connected
        gaps_ms: list[float] = []
        jobs = 0
        last_value, last_change = None, None
        next_beat = 0.0
        job_id, phase = 1, "ready"
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            now = time.monotonic()
            if now >= next_beat:
                beat = (beat + 1) % 65536
                plc.write_single_register(0, beat)
                next_beat = now + 0.1
            regs = plc.read_holding_registers(100, 14)
            now = time.monotonic()
            if regs:
                if regs[0] != last_value:
                    if last_change is not None:
                        gaps_ms.append((now - last_change) * 1000)
                    last_value, last_change = regs[0], now
                bits = regs[1]
                if phase == "ready" and bits & READY:
                    plc.write_multiple_registers(2, [job_id, 1])
                    plc.write_single_register(1, 1)
                    phase = "running"
                elif phase == "running" and bits & (DONE | ERROR):
                    plc.write_single_register(1, 0)
                    jobs += bits & DONE > 0
                    job_id = job_id % 65535 + 1
                    phase = "ready"
            time.sleep(0.005)
        states_per_s = None
        if isinstance(readers, subprocess.Popen) and not chromium and readers.stdout is not None:
            out, _ = readers.communicate(timeout=30)
            states_per_s = json.loads(out.strip().splitlines()[-1])["states_per_s"]
        return {
            "pages": pages,
            "gaps": len(gaps_ms),
            "gap_median_ms": statistics.median(gaps_ms),
            "gap_p99_ms": sorted(gaps_ms)[int(0.99 * (len(gaps_ms) - 1))],
            "gap_max_ms": max(gaps_ms),
            "jobs_ok": jobs,
            "states_per_s_per_page": states_per_s,
        }
    finally:
        if readers is not None and readers.poll() is None:
            readers.terminate()
            readers.wait(timeout=10)
        serve.send_signal(signal.SIGTERM)
        try:
            serve.wait(timeout=30)
        except subprocess.TimeoutExpired:
            serve.kill()
            serve.wait(timeout=10)
        shutil.rmtree(root, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="each round (s)")
    parser.add_argument("--pages", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=2, help="of each number of pages")
    parser.add_argument("--chromium", action="store_true", help="real browser tabs")
    parser.add_argument("--json", help="write the results here")
    parser.add_argument("--pages-of", help=argparse.SUPPRESS)  # the child process
    args = parser.parse_args(argv)
    if args.pages_of:
        pages_main(args.pages_of, args.pages, args.seconds)
        return 0
    rounds = []
    for _ in range(args.rounds):
        for pages in (0, args.pages):
            result = run_round(pages, args.seconds, args.chromium)
            rounds.append(result)
            print(json.dumps(result), file=sys.stderr, flush=True)
    rows = []
    for pages in (0, args.pages):
        mine = [r for r in rounds if r["pages"] == pages]
        rows.append(
            {
                "pages": pages,
                "gap_median_ms": statistics.median(r["gap_median_ms"] for r in mine),
                "gap_p99_ms": statistics.median(r["gap_p99_ms"] for r in mine),
                "gap_max_ms": max(r["gap_max_ms"] for r in mine),
                "jobs_ok": sum(r["jobs_ok"] for r in mine),
                "states_per_s_per_page": mine[0]["states_per_s_per_page"],
            }
        )
    kind = "chromium tabs" if args.chromium else "page clients (stream + status.json)"
    print(
        f"Modbus heartbeat gap, serve --backend sim --http, {args.rounds} x {args.seconds:.0f} s per row, {kind}"
    )
    print(
        f"{'pages':>5} {'median ms':>10} {'p99 ms':>8} {'max ms':>8} {'jobs':>5} {'states/s/page':>14}"
    )
    for r in rows:
        sps = "-" if r["states_per_s_per_page"] is None else f"{r['states_per_s_per_page']:.1f}"
        print(
            f"{r['pages']:>5} {r['gap_median_ms']:>10.1f} {r['gap_p99_ms']:>8.1f} {r['gap_max_ms']:>8.1f} {r['jobs_ok']:>5} {sps:>14}"
        )
    base, loaded = rows
    ratios = {
        "median": loaded["gap_median_ms"] / base["gap_median_ms"],
        "p99": loaded["gap_p99_ms"] / base["gap_p99_ms"],
    }
    print(
        f"ratio {args.pages} pages / 0 pages: median {ratios['median']:.2f}, p99 {ratios['p99']:.2f}"
    )
    if args.json:
        Path(args.json).write_text(
            json.dumps({"rows": rows, "rounds": rounds, "ratios": ratios}, indent=2)
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
