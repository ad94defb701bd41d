"""`cellrunner run --backend sim` journals a job that `cellrunner jobs` shows."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from tests.rig import CELL, TASK, cli, write_cell


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> tuple[Path, Path]:
    """The rig's small cell and task, laid out once for this module."""
    return write_cell(tmp_path_factory.mktemp("project"), CELL, TASK)


def test_run_on_the_twin_is_journaled(project):
    cell, task = project
    r = cli("run", str(cell), str(task), "--backend", "sim", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["ok"] and out["backend"] == "sim" and out["result_code"] == 0
    r = cli("jobs", str(cell), "--csv")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(io.StringIO(r.stdout)))
    assert rows[-1]["job_id"] == out["job_id"]
    assert (
        rows[-1]["result_code"] == "0"
        and rows[-1]["source"] == "cli"
        and float(rows[-1]["cycle_time_s"]) > 3
    )


def test_jobs_without_a_journal(tmp_path):
    (tmp_path / "c.yaml").write_text(
        "cell: c\nrobot: {model: ur5e, home: [0, -90, 90, -90, -90, 0]}\n"
    )
    r = cli("jobs", str(tmp_path / "c.yaml"))
    assert r.returncode == 0 and "no journal yet" in r.stderr


def test_ur_backend_without_a_host_is_an_input_error(tmp_path):
    (tmp_path / "c.yaml").write_text(
        "cell: c\nrobot: {model: ur5e, home: [0, -90, 90, -90, -90, 0]}\n"
    )
    (tmp_path / "t.yaml").write_text("task: t\nsteps: [{move: home}]\n")
    r = cli("run", str(tmp_path / "c.yaml"), str(tmp_path / "t.yaml"))
    assert r.returncode == 2
    assert "the ur backend needs a controller address" in r.stderr
