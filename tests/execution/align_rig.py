"""The align example cell in a test's own folder, and cellrunner run on it as a person
runs it (tests/execution/test_align.py, test_align_markers.py)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

from tests.conftest import ROOT
from tests.rig import ENV

CELL = ROOT / "cells" / "align_pick_ur10e.yaml"
TASK = ROOT / "tasks" / "align_pick.yaml"
BLIND = ROOT / "tasks" / "align_pick_blind.yaml"


#: as a person runs it: no MUJOCO_GL, cellrunner finds a GL backend for the camera itself
PLAIN_ENV = {k: v for k, v in ENV.items() if k != "MUJOCO_GL"}


def cellrunner(*args: str) -> tuple[int, dict, str]:
    r = subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", *args],
        capture_output=True, text=True, cwd=ROOT, env=PLAIN_ENV, timeout=300,
    )  # fmt: skip
    return r.returncode, json.loads(r.stdout) if r.stdout.startswith("{") else {}, r.stderr


def project(tmp_path, offset: str = "{xyz: [0.008, 0.006, 0], rpy: [0, 0, 4]}", task_edit=None):
    """The example cell and tasks in ``tmp_path``, the block at ``offset`` from its frame."""
    (tmp_path / "cells").mkdir(parents=True)
    (tmp_path / "tasks").mkdir()
    text = CELL.read_text().replace("{xyz: [0.008, 0.006, 0], rpy: [0, 0, 4]}", offset)
    assert offset in text
    (tmp_path / "cells" / "c.yaml").write_text(text)
    for t in (TASK, BLIND):
        shutil.copy(t, tmp_path / "tasks" / t.name)
    if task_edit is not None:
        t = tmp_path / "tasks" / TASK.name
        t.write_text(task_edit(t.read_text()))
    return (
        tmp_path / "cells" / "c.yaml",
        tmp_path / "tasks" / TASK.name,
        tmp_path / "tasks" / BLIND.name,
    )


def align_row(out: dict) -> dict:
    return next(s for s in out["steps"] if s["kind"] == "align")
