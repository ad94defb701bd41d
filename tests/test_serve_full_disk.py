"""`serve` on a disk that fills mid-job (a small tmpfs holds the journal), driven by an
independent PLC (pyModbusTCP) in this process and serve in its own: the PLC is never told
DONE before the result is journaled; it is told as soon as the space comes back."""

from __future__ import annotations

import signal
import time

from tests.execution.small_disk import fill, small_disk
from tests.rig import (
    BUSY,
    DONE,
    ERROR,
    JOB_ACK,
    JOB_REQ,
    READY,
    modbus_client,
    start_serve,
    wait_bits,
)
from tests.rig import CELL as DRYRUN_CELL
from tests.twin.cell_rig import free_port

WAIT_TASK = "task: dwell\nsteps:\n  - wait: 2.0\n"


def _project(tmp_path, disk) -> tuple[object, int]:
    host = "127.0.0.5"
    port = free_port(host)
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "t.yaml").write_text(WAIT_TASK)
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(
        DRYRUN_CELL
        + f"tasks: {{1: tasks/t.yaml}}\njournal: {disk / 'jobs.sqlite'}\n"
        + f"plc:\n  modbus: {{bind: {host}, port: {port}, heartbeat_timeout: 2.0}}\n"
    )
    return cell, port


def test_a_result_on_a_full_disk_is_held_then_delivered(tmp_path):
    with small_disk(tmp_path, 2048) as disk:
        cell, port = _project(tmp_path, disk)
        proc = start_serve(cell)
        beat = [0]
        try:
            client = modbus_client(port, "127.0.0.5")
            wait_bits(client, READY, 30, beat)
            client.write_multiple_registers(2, [301, 1])
            client.write_single_register(1, JOB_REQ)
            wait_bits(client, JOB_ACK | BUSY, 5, beat)
            filler = fill(disk)  # the disk fills while the job dwells
            ended_by = time.monotonic() + 2.0 + 3.0  # the dwell, and room to end it
            while time.monotonic() < ended_by:
                regs = wait_bits(client, 0, 5, beat)
                assert regs[1] & BUSY and not regs[1] & (DONE | ERROR), regs  # held, not told
                time.sleep(0.1)
            filler.unlink()  # space again
            regs = wait_bits(client, DONE, 10, beat)
            assert (regs[4], regs[5]) == (301, 0) and not regs[1] & BUSY, regs
            client.write_single_register(1, 0)
            wait_bits(client, READY, 10, beat)
        finally:
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err[-2000:]
        assert '"event": "result_held"' in err and '"level": "warning"' in err, err[-3000:]
        from cellrunner.execution.journal import SqliteJournal

        journal = SqliteJournal(disk / "jobs.sqlite").open()
        [record] = journal.last(5)
        journal.close()
    assert (record.client_job_id, record.result_code) == ("301", 0)


def test_sigterm_names_a_result_still_held(tmp_path):
    with small_disk(tmp_path, 2048) as disk:
        cell, port = _project(tmp_path, disk)
        proc = start_serve(cell)
        beat = [0]
        try:
            client = modbus_client(port, "127.0.0.5")
            wait_bits(client, READY, 30, beat)
            client.write_multiple_registers(2, [302, 1])
            client.write_single_register(1, JOB_REQ)
            wait_bits(client, JOB_ACK | BUSY, 5, beat)
            fill(disk)
            time.sleep(3.0)  # the dwell ends: its result waits for the disk
            assert wait_bits(client, BUSY, 5, beat)[1] & DONE == 0
        finally:
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-2000:]
    held = [line for line in err.splitlines() if "result_held_at_stop" in line]
    assert held and "the result of job" in held[0] and '"warning"' in held[0], err[-3000:]
    assert "could not be written" in err
