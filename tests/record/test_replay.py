"""``cellrunner replay``: a recording (Rerun's viewer, or how to open it without a
display) and a journaled job (its recording when kept, else its report)."""

from __future__ import annotations

import json
from pathlib import Path

from tests.record.record_rig import own_journal
from tests.rig import CELL, ENV, TASK, cli, write_cell

NO_DISPLAY = {k: v for k, v in ENV.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}


def test_replay_a_journaled_job_and_its_recording(tmp_path: Path) -> None:
    cell, task = write_cell(tmp_path, own_journal(tmp_path) + CELL, TASK)
    recording = tmp_path / "run.rrd"
    r = cli("run", str(cell), str(task), "--backend", "sim", "--json", "--record", str(recording))
    assert r.returncode == 0, r.stderr[-2000:]
    job_id = json.loads(r.stdout)["job_id"]

    out = tmp_path / "report"
    r = cli("replay", str(cell), job_id, "--out", str(out), env=NO_DISPLAY)
    assert r.returncode == 0, r.stderr
    page = (out / "index.html").read_text()
    assert page.count("<tr><td>") == 10  # the task's ten steps, as the journal has them
    assert "grip" in page and ">0 OK<" in page and job_id in page

    r = cli("replay", str(recording), env=NO_DISPLAY)  # no display: how to open it
    assert r.returncode == 0, r.stderr
    assert f"rerun --web-viewer {recording}" in r.stdout

    kept = tmp_path / "kept"
    kept.mkdir()
    recording.rename(kept / f"{job_id}.rrd")
    r = cli("replay", str(cell), job_id, "--recordings", str(kept), env=NO_DISPLAY)
    assert r.returncode == 0 and f"rerun {kept / job_id}.rrd" in r.stdout


def test_replay_bad_input_is_one_located_line(tmp_path: Path) -> None:
    cell, _ = write_cell(tmp_path, own_journal(tmp_path) + CELL, TASK)
    for args, where in (
        ((str(tmp_path / "none.rrd"),), f"{tmp_path / 'none.rrd'}:1:1: error: no such recording"),
        ((str(tmp_path / "job.txt"),), "error: replay"),
        ((str(cell), "no-such-job"), "no job no-such-job"),
    ):
        r = cli("replay", *args, env=NO_DISPLAY)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and where in lines[0], r.stderr
