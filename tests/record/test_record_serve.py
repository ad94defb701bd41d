"""``serve --record DIR`` on the twin, driven over Modbus TCP by an independent client:
one recording per job, named by its job id, each holding its own job; the folder's cap."""

from __future__ import annotations

import signal
import time
from pathlib import Path

from cellrunner.record.files import JobFolder
from tests.record.record_rig import own_journal, rrd_columns
from tests.rig import (
    CELL,
    DONE,
    ERROR,
    READY,
    TASK,
    free_port,
    modbus_client,
    plc_job,
    start_serve,
    wait_bits,
)

HOST = "127.0.0.5"


def _steps_text(path: Path) -> list[str]:
    from rerun.chunk import RrdReader

    lines = []
    for chunk in RrdReader(path).store().stream():
        if chunk.entity_path == "/steps":
            for rows in chunk.to_record_batch().column("TextLog:text").to_pylist():
                lines += rows
    return lines


def test_serve_records_one_file_per_job(tmp_path: Path) -> None:
    port = free_port(HOST)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        own_journal(tmp_path)
        + CELL
        + f"tasks: {{1: tasks/t.yaml}}\nplc:\n  modbus: {{bind: {HOST}, port: {port}, heartbeat_timeout: 2.0}}\n"
    )
    (tmp_path / "tasks" / "t.yaml").write_text(TASK)
    folder = tmp_path / "recordings"
    proc = start_serve(cell, "--backend", "sim", "--record", str(folder))
    try:
        client = modbus_client(port, HOST)
        beat = [0]
        for job_id in (41, 42):
            regs = plc_job(client, job_id, 1, [], beat)
            assert regs[1] & DONE and not regs[1] & ERROR, regs
            wait_bits(client, READY, 10, beat)
        time.sleep(0.5)  # the worker writes the second job's end
    finally:
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        stop_s = time.monotonic() - t0
    assert proc.returncode == 0, err[-2000:]
    # the recorder closes within the stop, and a signalled exit skips the interpreter's
    # teardown (1.6 s here without --record, 2.2-2.8 s with rerun loaded, before it did)
    assert stop_s < 2.0
    files = sorted(folder.iterdir())
    assert len(files) == 2 and all(p.suffix == ".rrd" for p in files)  # <journal job id>.rrd
    for path in files:
        lines = _steps_text(path)
        assert any(line.startswith(f"job {path.stem}: OK") for line in lines), lines
        assert sum(line.startswith("job ") for line in lines) == 1  # its own job only
        assert any(line.startswith("step 4 grip") for line in lines)


def test_run_on_the_arm_records_the_measured_arm(tmp_path: Path) -> None:
    """``run --backend ur --record`` against ``cellrunner twin`` (the unmodified ur_rtde
    client): no twin in the process, so the scene is the cell's model posed by the joints
    the controller reports; the arm moves in the recording as it moved."""
    import os

    import numpy as np

    from tests.rig import cli, write_cell
    from tests.twin.cell_rig import twin

    host = f"127.27.{os.getpid() % 250 + 1}.2"
    cell, task = write_cell(tmp_path, own_journal(tmp_path) + CELL, TASK)
    target = tmp_path / "arm.rrd"
    with twin(cell, host):
        r = cli(
            "run",
            str(cell),
            str(task),
            "--backend",
            "ur",
            "--robot-host",
            host,
            "--record",
            str(target),
        )
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"to {target}" in r.stderr
    components, moves = rrd_columns(target)
    assert any(
        p.startswith("/world/link6/") and "Mesh3D:vertex_positions" in c
        for p, c in components.items()
    )
    assert np.ptp(np.array(moves["/world/link6"])[:, :3], axis=0).max() > 0.1
    assert "LineStrips3D:strips" in components["/world/paths/planned"]


def test_job_folder_removes_the_oldest_beyond_its_cap(tmp_path: Path) -> None:
    import os

    for i in range(5):
        path = tmp_path / f"{i}.rrd"
        path.write_bytes(b"x" * 400_000)
        os.utime(path, (1_000_000 + i, 1_000_000 + i))
    (tmp_path / "notes.txt").write_bytes(b"x" * 900_000)  # not a recording: kept
    removed = JobFolder(tmp_path, max_mb=1.0).prune()
    assert [p.name for p in removed] == ["0.rrd", "1.rrd", "2.rrd"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["3.rrd", "4.rrd", "notes.txt"]
    assert JobFolder(tmp_path).path_of("3").name == "3-2.rrd"  # a PLC reused the id
