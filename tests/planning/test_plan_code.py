"""The plan store's key covers the code that plans a job (issue 33, s3000): a step kind's
planning (``steps/``) or an arm's link geometry changed by a release is another plan,
never the one stored before it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cellgen import generate
from tests.conftest import ROOT

DIGEST = "from cellrunner.planning.job_plan import code_digest; print(code_digest().hex())"

PLAN_AND_LIST = """
import json, sys
import numpy as np
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.job_plan import plan_job
from cellrunner.planning.world import CellWorld
cell = load_cell(sys.argv[1])
task = load_task(sys.argv[2], cell)
job = plan_job(CellWorld(cell), task, {}, np.radians(cell.cell.robot.home), use_cache=False)
assert job.ok, job.errors
files = [m.__file__ for n, m in sorted(sys.modules.items()) if n.split(".")[0] == "cellrunner"]
print(json.dumps(files))
"""


def _python(code: str, *args: str, path: Path) -> str:
    env = {**os.environ, "PYTHONPATH": str(path)}
    done = subprocess.run(
        [sys.executable, "-c", code, *args],
        env=env,
        cwd=path,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return done.stdout.strip()


@pytest.mark.parametrize(
    "changed",
    ["steps/release.py", "steps/_families.py", "model/arm_geometry/ur10.json.gz", "errors.py"],
)
def test_a_change_to_the_code_or_data_that_plans_changes_the_digest(tmp_path, changed):
    """Before: only ``planning/*.py`` and ``model/*.py`` were hashed, so the release that
    began to leave the pin in its hole as an obstacle kept the key, check approved the
    plan stored before it, and the twin's open jaws swept through the pin (100)."""
    copy = tmp_path / "src"
    shutil.copytree(
        ROOT / "cellrunner", copy / "cellrunner", ignore=shutil.ignore_patterns("__pycache__")
    )
    before = _python(DIGEST, path=copy)
    with (copy / "cellrunner" / changed).open("ab") as f:
        f.write(b"\n# changed\n")
    after = _python(DIGEST, path=copy)
    assert len(before) == len(after) == 64
    assert after != before


def test_every_module_that_plans_a_job_is_in_the_digest(tmp_path):
    """A fresh process plans the generated s3000 job (hole_fit: pick, insert, release,
    retreat, move home); every module of the package it imported is hashed."""
    case = generate(3000, "hole_fit")
    cell, task = case.write(tmp_path / case.name)
    from cellrunner.planning.job_plan import code_files

    imported = json.loads(_python(PLAN_AND_LIST, str(cell), str(task), path=ROOT))
    hashed = {str(p) for p in code_files()}
    assert any(f.endswith("steps/release.py") for f in imported)
    assert any(f.endswith("steps/insert.py") for f in imported)
    missing = sorted(f for f in imported if str(Path(f).resolve()) not in hashed)
    assert missing == []


def test_code_files_leave_compiled_caches_out():
    from cellrunner.planning.job_plan import code_files

    files = code_files()
    assert files == sorted(files)
    assert not [f for f in files if "__pycache__" in f.parts or f.suffix == ".pyc"]
