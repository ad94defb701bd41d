"""The generated cells kept in tests/data/generated (bench/cellgen.py wrote them when
they disagreed, or to pin a case): copied to a test's folder (their plans and journal go
there), checked and rehearsed as a user runs them."""

from __future__ import annotations

import shutil
from pathlib import Path

from bench.agreement import cli
from tests.conftest import ROOT

GENERATED = ROOT / "tests" / "data" / "generated"


def copied(name: str, tmp_path: Path) -> tuple[str, str]:
    """The cell and task files of generated case ``name``, copied into ``tmp_path``."""
    shutil.copytree(GENERATED / name, tmp_path, dirs_exist_ok=True)
    return str(tmp_path / "cell.yaml"), str(tmp_path / "task.yaml")


def approved_and_rehearsed(cell: str, task: str) -> tuple[dict, dict]:
    """``check`` (no plan cache) approves the job and the twin ends it 0: their objects."""
    code, checked = cli("check", cell, task, "--no-cache")
    assert (code, checked["ok"]) == (0, True), checked
    _, run = cli("dry-run", cell, task)
    assert (run["result_code"], run["result_text"]) == (0, "OK"), run["result_text"]
    return checked, run
