"""servoJ streaming at the controller rate against the virtual controller, through ur_rtde.

Starts ``python -m cellrunner.twin MODEL --host HOST`` in its own process, connects the
unmodified ur_rtde RTDEControl/RTDEReceive clients and measures:

- client period jitter: deviation of the time between consecutive servoJ calls from
  the nominal period, paced by ur_rtde's initPeriod/waitPeriod (p50/p99/max);
- twin loop jitter: the virtual controller's own tick period deviation (fault channel
  ``timing``);
- tracking error: |actual_q - commanded q| during a sine stream (rad, worst joint);
- command-to-motion latency: from sending a servoJ step to the receive side seeing the
  arm move (> 1e-5 rad), repeated from standstill.

Then the jog's servo chain (``bench/servo_udp.py``) in the same run: ``cellrunner twin`` of
cells/align_pick_ur10e.yaml with ``cellrunner jog --input udp:PORT`` streaming from a raw
socket: UDP datagram to the first changed set-point and to measured motion (p50/p99,
target <= 10 ms at 500 Hz; the peer is the servoJ command-to-motion latency above),
deviation from a commanded straight line at 0.1 m/s (target <= 0.5 mm), the stop after the
last datagram; and ``align`` over random part offsets within its max_correction box
(correction error, looks, success: target >= 98 % placed within tolerance).

Usage: ``PYTHONPATH=. python bench/bench_servo.py [--model ur5e] [--seconds 5]
[--udp-probes 30] [--align-runs 50]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import socket
import subprocess
import sys
import time

import numpy as np


def fault(host: str, command: str) -> str:
    with socket.create_connection((host, 29990), timeout=3) as sock:
        sock.sendall((command + "\n").encode())
        return sock.makefile().readline().strip().removeprefix("ok ")


def start_twin(model: str, host: str) -> subprocess.Popen:
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([os.getcwd(), os.environ.get("PYTHONPATH", "")])
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "cellrunner.twin", model, "--host", host], env=env
    )
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        try:
            fault(host, "ping")
            return proc
        except OSError:
            time.sleep(0.05)
    proc.kill()
    raise SystemExit(f"twin on {host} did not come up")


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def bench(host: str, seconds: float, rate_hz: float) -> dict[str, list[float] | dict]:
    import rtde_control
    import rtde_receive

    try:  # as ur_rtde itself does on a real-time kernel: the streaming thread gets SCHED_FIFO
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        realtime = True
    except (AttributeError, OSError):
        realtime = False
    receive = rtde_receive.RTDEReceiveInterface(host)
    control = rtde_control.RTDEControlInterface(host)
    period = 1.0 / rate_hz
    try:
        q0 = np.array(receive.getActualQ())
        sends, errors = [], []
        n = int(seconds / period)
        for i in range(n):
            t_cycle = control.initPeriod()
            q = q0.copy()
            phase = 2 * math.pi * i * period / 2.0
            q[0] += 0.3 * math.sin(phase)
            q[1] += 0.2 * (1 - math.cos(phase))
            sends.append(time.perf_counter())
            control.servoJ(q.tolist(), 0.0, 0.0, period, 0.03, 1000)
            errors.append(float(np.max(np.abs(np.array(receive.getActualQ()) - q))))
            control.waitPeriod(t_cycle)
        control.servoStop(4.0)
        time.sleep(0.3)

        latencies = []
        for k in range(40):
            q_here = np.array(receive.getActualQ())
            target = q_here.copy()
            target[5] += 0.01 * (1 if k % 2 == 0 else -1)
            t0 = time.perf_counter()
            deadline = t0 + 0.5
            seen = None
            while time.perf_counter() < deadline:
                control.servoJ(target.tolist(), 0.0, 0.0, period, 0.03, 1000)
                if abs(receive.getActualQ()[5] - q_here[5]) > 1e-5:
                    seen = time.perf_counter()
                    break
                time.sleep(0.0002)
            if seen is not None:
                latencies.append(seen - t0)
            control.servoStop(4.0)
            time.sleep(0.1)
        twin_timing = json.loads(fault(host, "timing"))
        steps = np.diff(sends)
        return {
            "period": period,
            "client_jitter": list(np.abs(steps - period)),
            "client_periods": list(steps),
            "errors": errors[int(0.1 / period) :],
            "latencies": latencies,
            "twin": twin_timing,
            "realtime": realtime,
        }
    finally:
        control.stopScript()
        control.disconnect()
        receive.disconnect()


def main() -> bool:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--model", default="ur5e")
    parser.add_argument("--host", default="127.0.9.2")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--udp-probes", type=int, default=30)
    parser.add_argument("--align-runs", type=int, default=50)
    parser.add_argument("--udp-host", default="127.0.9.3")
    args = parser.parse_args()
    twin = start_twin(args.model, args.host)
    try:
        from cellrunner.model.robots import robot_spec

        r = bench(args.host, args.seconds, robot_spec(args.model).rate_hz)
    finally:
        twin.terminate()
        twin.wait(5)
    ms = 1e3
    twin_t = r["twin"]
    rows = [
        (
            "client period (ms)",
            pct(r["client_periods"], 50) * ms,
            pct(r["client_periods"], 99) * ms,
            max(r["client_periods"]) * ms,
        ),
        (
            "client jitter |dt-T| (ms)",
            pct(r["client_jitter"], 50) * ms,
            pct(r["client_jitter"], 99) * ms,
            max(r["client_jitter"]) * ms,
        ),
        (
            "twin loop jitter (ms)",
            twin_t["jitter_p50_s"] * ms,
            twin_t["jitter_p99_s"] * ms,
            twin_t["jitter_max_s"] * ms,
        ),
        (
            "tracking error (mrad)",
            pct(r["errors"], 50) * 1e3,
            pct(r["errors"], 99) * 1e3,
            max(r["errors"]) * 1e3,
        ),
        (
            "cmd-to-motion latency (ms)",
            pct(r["latencies"], 50) * ms,
            pct(r["latencies"], 99) * ms,
            max(r["latencies"] or [float("nan")]) * ms,
        ),
    ]
    print(
        f"\nservoJ bench: {args.model} at {1 / r['period']:.0f} Hz, {args.seconds:g} s, "
        f"{len(r['client_periods']) + 1} set-points, {len(r['latencies'])} latency probes, "
        f"{os.cpu_count()} CPUs, client SCHED_FIFO {'on' if r['realtime'] else 'off'}, "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    print(f"{'metric':<28}{'p50':>10}{'p99':>10}{'max':>10}")
    for name, p50, p99, mx in rows:
        print(f"{name:<28}{p50:>10.3f}{p99:>10.3f}{mx:>10.3f}")
    target_ok = pct(r["client_jitter"], 99) < 1e-3
    print(f"\nclient p99 jitter < 1 ms: {'yes' if target_ok else 'NO'}")
    return servo_and_align(args, r["latencies"]) and target_ok


def servo_and_align(args: argparse.Namespace, servoj_latencies: list[float]) -> bool:
    """The jog's UDP servo and the align step; True when every target is met."""
    from bench.servo_udp import align_figures, servo_figures

    u = servo_figures(args.udp_host, args.udp_probes)
    ms = 1e3
    peer = pct(servoj_latencies, 50)
    print(
        f"\njog --input udp against cellrunner twin (UR10e, 500 Hz), {len(u['to_setpoint'])} "
        f"probes, load average {os.getloadavg()[0]:.2f}"
    )
    print(f"{'metric':<40}{'p50':>10}{'p99':>10}{'max':>10}")
    for name, values in (
        ("datagram -> first set-point (ms)", u["to_setpoint"]),
        ("datagram -> measured motion (ms)", u["to_motion"]),
    ):
        print(
            f"{name:<40}{pct(values, 50) * ms:>10.2f}{pct(values, 99) * ms:>10.2f}{max(values) * ms:>10.2f}"
        )
    print(
        f"ratio datagram->motion p50 / servoJ->motion p50 (the peer, above): "
        f"{pct(u['to_motion'], 50) / peer:.2f}x"
    )
    print(
        f"straight line at 0.1 m/s: largest distance {u['line_max_mm']:.3f} mm, "
        f"p99 {u['line_p99_mm']:.3f} mm (travel {u['travel_mm']:.1f} mm)"
    )
    print(f"stop after the last datagram: {u['stop_mm']:.1f} mm in {u['stop_s']:.3f} s")
    a = align_figures(args.align_runs)
    placed = sum(1 for c in a["codes"] if c == 0)
    print(
        f"\nalign over {len(a['codes'])} random offsets (x, y within 15 mm, yaw within 8 deg), "
        f"dry-run of tasks/align_pick.yaml"
    )
    print(
        f"correction error: median {np.median(a['errors_mm']):.2f} mm, max "
        f"{max(a['errors_mm']):.2f} mm; yaw median {np.median(a['errors_deg']):.2f} deg, max "
        f"{max(a['errors_deg']):.2f} deg; looks median {np.median(a['looks']):.0f}, max "
        f"{max(a['looks'])}; placed within tolerance {placed}/{len(a['codes'])} "
        f"({placed / len(a['codes']) * 100:.0f} %); results {sorted(set(a['codes']))}"
    )
    for failure in a["failures"]:
        print(f"  not placed: {failure}")
    ok = (
        pct(u["to_setpoint"], 99) <= 0.010
        and pct(u["to_motion"], 99) <= 0.010
        and u["line_max_mm"] <= 0.5
        and placed / len(a["codes"]) >= 0.98
    )
    print(f"\nservo and align targets met: {'yes' if ok else 'NO'}")
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
