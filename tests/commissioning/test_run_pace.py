"""`run --speed F` streams the very set-points `check` approved, stretched in time only,
and `run --step` waits for Enter before each step: end to end through ur_rtde against
`cellrunner twin`, comparing what the twin received sample by sample."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.commissioning.conftest import cli, fault, twin, write_project
from tests.conftest import ROOT

HOST = "127.0.0.150"

#: a short job for the pace test (2 s at full speed, 8 s at a quarter): a joint move, a
#: straight lift and a joint move home, so the streamed set-points cross both kinds of
#: step and two joins between pieces
PACE_TASK = """\
task: pace
steps:
  - move: {to: [60, -90, 90, -90, -90, 0]}
  - lift: {distance: 0.1}
  - move: home
"""


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    return write_project(tmp_path_factory.mktemp("pace"))


def _recorded_run(cell, task, tmp_path, *extra) -> tuple[dict, np.ndarray]:
    fault(HOST, "record on")
    r = cli("run", str(cell), str(task), "--robot-host", HOST, "--json", *extra)
    assert r.returncode == 0, r.stderr[-3000:]
    path = tmp_path / f"servo{len(list(tmp_path.iterdir()))}.npy"
    fault(HOST, f"record save {path}")
    fault(HOST, "record off")
    return json.loads(r.stdout), np.load(path)


def test_quarter_speed_streams_the_approved_set_points_four_times_slower(project, tmp_path):
    cell, _ = project
    task = tmp_path / "pace.yaml"
    task.write_text(PACE_TASK)
    r = cli("check", str(cell), str(task), "--save-plan", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    plan = json.loads((tmp_path / "plan.json").read_text())
    approved = [np.radians(np.array(s["samples"])[:, 1:]) for s in plan["steps"] if s["samples"]]
    # what the engine streams: every piece after the first without its shared start sample
    approved_stream = np.vstack([approved[0], *[a[1:] for a in approved[1:]]])
    with twin(cell, HOST):
        full, at_1 = _recorded_run(cell, task, tmp_path)
        slow, at_q = _recorded_run(cell, task, tmp_path, "--speed", "0.25")
    q1, qq = at_1[:, 1:], at_q[:, 1:]
    assert np.allclose(q1, approved_stream, atol=1e-8), "full speed streams what check approved"
    assert len(qq) == 4 * (len(q1) - 1) + 1
    assert np.array_equal(qq[::4], q1), "every 4th set-point is an approved one, bit for bit"
    for j in (1, 2, 3):  # the ones between lie on the approved segment, in order
        assert np.allclose(qq[j::4], q1[:-1] + j / 4 * (q1[1:] - q1[:-1]), atol=1e-12)
    period_s = 1.0 / plan["rate_hz"]
    assert np.median(np.diff(at_q[:, 0])) == pytest.approx(period_s), (
        "one set-point per controller period"
    )
    # 4x the set-points at one per controller period is 4x the time. Measured times add the
    # client's pacing delays on a loaded machine (late set-points only ever stretch them),
    # so they are bounded from below here
    span_1, span_q = (
        at_1[-1, 0] - at_1[0, 0],
        at_q[-1, 0] - at_q[0, 0],
    )  # controller time at arrival
    assert (len(qq) - 1) * period_s == pytest.approx(4 * (len(q1) - 1) * period_s)
    assert span_q / span_1 > 3.6
    assert slow["cycle_time_s"] / full["cycle_time_s"] > 3.6
    assert [s["status"] for s in slow["steps"]] == ["ok"] * 3


def test_speed_outside_zero_to_one_is_an_input_error(project):
    cell, task = project
    for bad in ("0", "1.5", "-0.2"):
        r = cli("run", str(cell), str(task), "--robot-host", HOST, "--speed", bad)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert (
            f"--speed {float(bad):g}: give a fraction of the approved pace, 0 < F <= 1" in r.stderr
        )


def _read_until(stream, needle: str, timeout_s: float) -> list[str]:
    lines: list[str] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = stream.readline()
        if not line:
            break
        lines.append(line)
        if needle in line:
            return lines
    raise AssertionError(f"{needle!r} not seen in {lines[-20:]}")


def test_step_mode_waits_for_enter_before_each_step(project, tmp_path):
    cell, task = project
    with twin(cell, HOST):
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "cellrunner.cli.main",
                "run",
                str(cell),
                str(task),
                "--robot-host",
                HOST,
                "--step",
                "--json",
            ],
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "COLUMNS": "200"},
        )
        try:
            shown = []
            for _n in range(4):
                lines = _read_until(proc.stderr, "press Enter", 60)
                shown.append(next(line for line in lines if line.startswith("next: ")))
                fault(HOST, "record on")
                time.sleep(0.5)
                assert fault(HOST, f"record save {tmp_path / 'idle.npy'}") == "0", (
                    "nothing streamed before Enter"
                )
                proc.stdin.write("\n")
                proc.stdin.flush()
            fault(HOST, "record off")
            out, err = proc.communicate(timeout=60)
        finally:
            proc.kill() if proc.poll() is None else None
    assert proc.returncode == 0, err[-2000:]
    assert json.loads(out)["result_code"] == 0
    assert shown[0].startswith(
        "next: step 1 approach 'pick': TCP to xyz [0.7000, -0.4000, 0.9300] m, rpy [180.00, "
    )
    assert shown[1].startswith(
        "next: step 2 descend 'pick': TCP to xyz [0.7000, -0.4000, 0.8300] m"
    )
    assert shown[2] == "next: step 3 lift: 0.1 m straight\n"
    assert (
        shown[3]
        == "next: step 4 move 'home': joints to [0.00, -90.00, 90.00, -90.00, -90.00, 0.00] deg\n"
    )


def test_step_mode_aborts_when_no_one_can_press_enter(project):
    cell, task = project
    with twin(cell, HOST):
        r = cli(
            "run",
            str(cell),
            str(task),
            "--robot-host",
            HOST,
            "--step",
            "--json",
            stdin=subprocess.DEVNULL,
        )
    assert r.returncode == 1, r.stderr[-2000:]
    assert "end of input: no one can confirm the next step; aborting" in r.stderr
    out = json.loads(r.stdout)
    assert out["result_code"] == 106 and [s["status"] for s in out["steps"]] == ["skipped"] * 4
